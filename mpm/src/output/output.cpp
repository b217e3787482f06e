// The run's files: VTK XML UnstructuredGrid frames (one vertex per material point), the PVD
// index, the series CSVs and the final profile.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <ostream>
#include <sstream>
#include <string>

#include <granflow/io/output.hpp>
#include <granflow/mpm/output.hpp>

namespace granflow::mpm {
namespace {

// Series and profiles: synced with the checkpoint or the manifest, like the frames.
void write_buffered(const std::string& path, const std::string& text) {
  io::write_file(path, text, io::Durability::Buffered);
}

bool little_endian() {
  const std::uint16_t one = 1;
  unsigned char b;
  std::memcpy(&b, &one, 1);
  return b == 1;
}

// Base64 of n bytes; the whole groups of three on all cores (a frame of 8e6 points is 1.5 GB).
std::string base64(const unsigned char* p, size_t n) {
  static const char* tab = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out((n + 2) / 3 * 4, '=');
  const long groups = static_cast<long>(n / 3);
  char* o = out.data();
#pragma omp parallel for schedule(static) if (groups > (1L << 16))
  for (long g = 0; g < groups; ++g) {
    const unsigned char* q = p + 3 * g;
    const unsigned v = (unsigned(q[0]) << 16) | (unsigned(q[1]) << 8) | unsigned(q[2]);
    char* w = o + 4 * g;
    w[0] = tab[(v >> 18) & 63];
    w[1] = tab[(v >> 12) & 63];
    w[2] = tab[(v >> 6) & 63];
    w[3] = tab[v & 63];
  }
  if (const size_t rest = n - 3 * static_cast<size_t>(groups)) {  // 1 or 2 bytes: '=' padding
    const unsigned char* q = p + 3 * groups;
    const unsigned v = (unsigned(q[0]) << 16) | (rest > 1 ? unsigned(q[1]) << 8 : 0u);
    char* w = o + 4 * groups;
    w[0] = tab[(v >> 18) & 63];
    w[1] = tab[(v >> 12) & 63];
    if (rest > 1) w[2] = tab[(v >> 6) & 63];
  }
  return out;
}

// One inline DataArray; `comp` components interleaved from component-major input.
template <class T>
void data_array(std::ostream& os, const char* type, const char* name, int comp, const std::vector<T>& v, bool binary) {
  os << "        <DataArray type=\"" << type << "\" Name=\"" << name << "\" NumberOfComponents=\"" << comp
     << "\" format=\"" << (binary ? "binary" : "ascii") << "\">\n";
  if (binary) {
    const std::uint32_t bytes = static_cast<std::uint32_t>(v.size() * sizeof(T));
    std::string buf(sizeof(bytes) + bytes, '\0');
    std::memcpy(buf.data(), &bytes, sizeof(bytes));
    std::memcpy(buf.data() + sizeof(bytes), v.data(), bytes);
    os << "          " << base64(reinterpret_cast<const unsigned char*>(buf.data()), buf.size()) << "\n";
  } else {
    os.precision(10);
    // +v promotes 8-bit types so they print as numbers, not characters
    for (size_t i = 0; i < v.size(); ++i) os << (i % 9 == 0 ? "\n          " : " ") << +v[i];
    os << "\n";
  }
  os << "        </DataArray>\n";
}

std::vector<double> interleave3(const std::vector<double>& a, long n, int dim) {
  std::vector<double> o(3 * n, 0.0);
  for (long i = 0; i < n; ++i)
    for (int d = 0; d < dim; ++d) o[3 * i + d] = a[d * n + i];
  return o;
}

static_assert(sizeof(int) == 4, "material and body ids are written as Int32");

// One point array of a frame and where its values come from: a vector as it is, three
// components interleaved from component-major input, or the vertex cells (made up here).
struct Array {
  enum class Source { Values, Interleaved, Connectivity, Offsets, Types };
  Source source;
  const char* type;  // VTK's name: Float64, Int32 or UInt8
  const char* name;
  int components = 1;
  const std::vector<double>* doubles = nullptr;  // Values (Float64) and Interleaved
  const std::vector<int>* ints = nullptr;         // Values (Int32)

  std::size_t value_size() const { return type[0] == 'F' ? 8 : type[0] == 'I' ? 4 : 1; }
  std::uint64_t bytes(long n) const { return std::uint64_t(n) * components * value_size(); }
};

// The arrays of a frame by section, in the order they are written.
struct FrameArrays {
  std::vector<Array> points, cells, point_data;
};

FrameArrays frame_arrays(const Frame& fr, const std::vector<std::string>& fields) {
  auto wanted = [&](const char* name) {
    return fields.empty() || std::find(fields.begin(), fields.end(), name) != fields.end();
  };
  using S = Array::Source;
  const size_t n = static_cast<size_t>(fr.n);
  FrameArrays a;
  a.points.push_back({S::Interleaved, "Float64", "position", 3, &fr.x});
  a.cells = {{S::Connectivity, "Int32", "connectivity"}, {S::Offsets, "Int32", "offsets"}, {S::Types, "UInt8", "types"}};
  if (wanted("velocity")) a.point_data.push_back({S::Interleaved, "Float64", "velocity", 3, &fr.v});
  const std::pair<const char*, const std::vector<double>*> scalars[] = {
      {"p", &fr.p},         {"q", &fr.q},     {"eps_pd", &fr.eps_pd}, {"T", &fr.T},
      {"eta_c", &fr.eta_c}, {"K_col", &fr.K_col}, {"e", &fr.e},       {"sigma_xx", &fr.sxx},
      {"sigma_yy", &fr.syy}, {"sigma_xy", &fr.sxy}};
  for (const auto& [name, v] : scalars)
    if (v->size() == n && wanted(name)) a.point_data.push_back({S::Values, "Float64", name, 1, v});
  for (const auto& [name, v] : {std::pair<const char*, const std::vector<int>*>{"material", &fr.material}, {"body", &fr.body}})
    if (v->size() == n && wanted(name)) a.point_data.push_back({S::Values, "Int32", name, 1, nullptr, v});
  return a;
}

// Inline (base64 or ASCII): each array whole, as the writer before issue 49 did, byte for byte.
void inline_array(std::ostream& os, const Array& a, const Frame& fr, bool binary) {
  const long n = fr.n;
  switch (a.source) {
    case Array::Source::Interleaved:
      data_array(os, a.type, a.name, 3, interleave3(*a.doubles, n, fr.dim), binary);
      return;
    case Array::Source::Values:
      if (a.doubles) data_array(os, a.type, a.name, 1, *a.doubles, binary);
      else data_array(os, a.type, a.name, 1, *a.ints, binary);
      return;
    case Array::Source::Connectivity:
    case Array::Source::Offsets: {
      const std::int32_t first = a.source == Array::Source::Offsets ? 1 : 0;
      std::vector<std::int32_t> v(n);
      for (long i = 0; i < n; ++i) v[i] = static_cast<std::int32_t>(i + first);
      data_array(os, a.type, a.name, 1, v, binary);
      return;
    }
    case Array::Source::Types:
      data_array(os, a.type, a.name, 1, std::vector<std::uint8_t>(n, 1), binary);  // VTK_VERTEX
      return;
  }
}

// Appended raw data: the array's byte count (UInt64), then its values, from the frame's vectors
// as they are or through a buffer of kChunk points (never a whole copy).
constexpr long kChunk = 1 << 15;

template <class T>
void put(io::AtomicFile& f, const T* p, std::size_t count) {
  f.write(std::string_view(reinterpret_cast<const char*>(p), count * sizeof(T)));
}

void append_raw(io::AtomicFile& f, const Array& a, const Frame& fr) {
  const long n = fr.n;
  const std::uint64_t bytes = a.bytes(n);
  put(f, &bytes, 1);
  switch (a.source) {
    case Array::Source::Values:
      if (a.doubles) put(f, a.doubles->data(), n);
      else put(f, a.ints->data(), n);
      return;
    case Array::Source::Interleaved: {
      std::vector<double> buf(3 * kChunk, 0.0);  // 2D: the third component stays 0
      for (long i0 = 0; i0 < n; i0 += kChunk) {
        const long m = std::min(kChunk, n - i0);
        for (int d = 0; d < fr.dim; ++d) {
          const double* src = a.doubles->data() + d * n + i0;
          for (long i = 0; i < m; ++i) buf[3 * i + d] = src[i];
        }
        put(f, buf.data(), 3 * m);
      }
      return;
    }
    case Array::Source::Connectivity:
    case Array::Source::Offsets: {
      const long first = a.source == Array::Source::Offsets ? 1 : 0;
      std::vector<std::int32_t> buf(kChunk);
      for (long i0 = 0; i0 < n; i0 += kChunk) {
        const long m = std::min(kChunk, n - i0);
        for (long i = 0; i < m; ++i) buf[i] = static_cast<std::int32_t>(i0 + i + first);
        put(f, buf.data(), m);
      }
      return;
    }
    case Array::Source::Types: {
      const std::vector<std::uint8_t> buf(kChunk, 1);  // VTK_VERTEX
      for (long i0 = 0; i0 < n; i0 += kChunk) put(f, buf.data(), std::min(kChunk, n - i0));
      return;
    }
  }
}

}  // namespace

void write_vtu(const std::string& path, const Frame& fr, FrameFormat format, const std::vector<std::string>& fields,
               io::Durability durability) {
  auto wanted = [&](const char* name) {
    return fields.empty() || std::find(fields.begin(), fields.end(), name) != fields.end();
  };
  const FrameArrays arrays = frame_arrays(fr, fields);
  const bool raw = format == FrameFormat::Raw;
  io::AtomicFile file(path, durability);
  std::ostream& os = file.stream();
  const long n = fr.n;
  // UInt64 byte counts come with version 1.0 of the format (VTK's own writer does the same)
  os << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"" << (raw ? "1.0" : "0.1")
     << "\" byte_order=\"" << (little_endian() ? "LittleEndian" : "BigEndian") << "\" header_type=\""
     << (raw ? "UInt64" : "UInt32") << "\">\n"
     << "  <UnstructuredGrid>\n    <Piece NumberOfPoints=\"" << n << "\" NumberOfCells=\"" << n << "\">\n";
  std::uint64_t offset = 0;  // of the next array in the appended data
  auto section = [&](const std::vector<Array>& list) {
    for (const Array& a : list) {
      if (!raw) {
        inline_array(os, a, fr, format == FrameFormat::Base64);
        continue;
      }
      os << "        <DataArray type=\"" << a.type << "\" Name=\"" << a.name << "\" NumberOfComponents=\""
         << a.components << "\" format=\"appended\" offset=\"" << offset << "\"/>\n";
      offset += sizeof(std::uint64_t) + a.bytes(n);
    }
  };
  os << "      <Points>\n";
  section(arrays.points);
  os << "      </Points>\n      <Cells>\n";
  section(arrays.cells);
  os << "      </Cells>\n      <PointData";
  if (wanted("p")) os << " Scalars=\"p\"";  // as before output.fields, light frames included
  if (wanted("velocity")) os << " Vectors=\"velocity\"";
  os << ">\n";
  section(arrays.point_data);
  os << "      </PointData>\n    </Piece>\n  </UnstructuredGrid>\n";
  if (raw) {
    os << "  <AppendedData encoding=\"raw\">\n   _";
    for (const auto* list : {&arrays.points, &arrays.cells, &arrays.point_data})
      for (const Array& a : *list) append_raw(file, a, fr);
    os << "\n  </AppendedData>\n";
  }
  os << "</VTKFile>\n";
  file.commit();
}

std::string frame_file_name(int number, const std::string& tag) {
  char digits[16];
  std::snprintf(digits, sizeof digits, "%04d", number);
  return "frame_" + std::string(digits) + tag + ".vtu";
}

void write_pvd(const std::string& path, const std::vector<std::pair<double, std::string>>& frames) {
  io::AtomicFile file(path, io::Durability::Buffered);
  {
    std::ostream& os = file.stream();
    os << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n  <Collection>\n";
    os.precision(10);
    for (const auto& [t, f] : frames)
      os << "    <DataSet timestep=\"" << t << "\" group=\"\" part=\"0\" file=\"" << f << "\"/>\n";
    os << "  </Collection>\n</VTKFile>\n";
  }
  file.commit();
}

void write_series_csv(const std::string& dir, const Scene& sc, const std::vector<SeriesRow>& series,
                      const std::vector<TrackRow>& tracks) {
  std::ostringstream a;
  a.precision(8);
  a << "t,t_flow,stage,runout,height,max_speed,kinetic_energy,mean_T,max_T\n";
  for (const auto& r : series)
    a << r.t << ',' << r.t_flow << ',' << r.stage << ',' << r.m.runout << ',' << r.m.height << ',' << r.m.max_speed
      << ',' << r.m.kinetic_energy << ',' << r.m.mean_T << ',' << r.m.max_T << '\n';
  write_buffered(dir + "/runout.csv", a.str());
  std::ostringstream b;
  b.precision(8);
  b << "t,t_flow,name,x,y,vx,vy,p,q,eps_pd,T,eta_c,K_col\n";
  for (const auto& r : tracks)
    b << r.t << ',' << r.t_flow << ',' << io::csv_field(sc.tracks[r.track].name) << ',' << r.x << ',' << r.y << ',' << r.vx << ','
      << r.vy << ',' << r.p << ',' << r.q << ',' << r.eps_pd << ',' << r.T << ',' << r.eta_c << ',' << r.K_col << '\n';
  write_buffered(dir + "/tracked.csv", b.str());
}

void write_profile_csv(const std::string& path, const std::vector<std::pair<double, double>>& surface) {
  std::ostringstream c;
  c.precision(8);
  c << "x,surface_y\n";
  for (const auto& [x, y] : surface) c << x << ',' << y << '\n';
  write_buffered(path, c.str());
}

}  // namespace granflow::mpm
