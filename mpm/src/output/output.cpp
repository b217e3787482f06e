// VTK XML UnstructuredGrid of vertices (one per material point) and the PVD index.
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <ostream>

#include <granflow/io/output.hpp>
#include <granflow/mpm/driver.hpp>

namespace granflow::mpm {
namespace {

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

// One DataArray; `comp` components interleaved from component-major input.
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

}  // namespace

void write_vtu(const std::string& path, const Frame& fr, bool binary, const std::vector<std::string>& fields) {
  auto wanted = [&](const char* name) {
    return fields.empty() || std::find(fields.begin(), fields.end(), name) != fields.end();
  };
  io::AtomicFile file(path, io::Durability::Buffered);  // synced with the checkpoint or the manifest
  {
    std::ostream& os = file.stream();
    const long n = fr.n;
    os << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\""
       << (little_endian() ? "LittleEndian" : "BigEndian") << "\" header_type=\"UInt32\">\n"
       << "  <UnstructuredGrid>\n    <Piece NumberOfPoints=\"" << n << "\" NumberOfCells=\"" << n << "\">\n";
    os << "      <Points>\n";
    data_array(os, "Float64", "position", 3, interleave3(fr.x, n, fr.dim), binary);
    os << "      </Points>\n      <Cells>\n";
    std::vector<std::int32_t> conn(n), offs(n);
    std::vector<std::uint8_t> types(n, 1);  // VTK_VERTEX
    for (long i = 0; i < n; ++i) {
      conn[i] = static_cast<std::int32_t>(i);
      offs[i] = static_cast<std::int32_t>(i + 1);
    }
    data_array(os, "Int32", "connectivity", 1, conn, binary);
    data_array(os, "Int32", "offsets", 1, offs, binary);
    data_array(os, "UInt8", "types", 1, types, binary);
    os << "      </Cells>\n      <PointData";
    if (wanted("p")) os << " Scalars=\"p\"";  // as before output.fields, light frames included
    if (wanted("velocity")) os << " Vectors=\"velocity\"";
    os << ">\n";
    if (wanted("velocity")) data_array(os, "Float64", "velocity", 3, interleave3(fr.v, n, fr.dim), binary);
    const std::pair<const char*, const std::vector<double>*> scalars[] = {
        {"p", &fr.p},         {"q", &fr.q},     {"eps_pd", &fr.eps_pd}, {"T", &fr.T},
        {"eta_c", &fr.eta_c}, {"K_col", &fr.K_col}, {"e", &fr.e},       {"sigma_xx", &fr.sxx},
        {"sigma_yy", &fr.syy}, {"sigma_xy", &fr.sxy}};
    for (const auto& [name, v] : scalars)
      if (v->size() == static_cast<size_t>(n) && wanted(name)) data_array(os, "Float64", name, 1, *v, binary);
    for (const auto& [name, v] : {std::pair<const char*, const std::vector<int>*>{"material", &fr.material}, {"body", &fr.body}})
      if (v->size() == static_cast<size_t>(n) && wanted(name)) data_array(os, "Int32", name, 1, *v, binary);
    os << "      </PointData>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n";
  }
  file.commit();
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

}  // namespace granflow::mpm
