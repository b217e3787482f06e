// Outputs read back with an independent little VTU reader, and bad scenes rejected with a
// message naming the key.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>

#include <granflow/mpm/driver.hpp>

#include <granflow/io/input_error.hpp>
#include <granflow/mpm/scene_file.hpp>

using namespace granflow;
using namespace granflow::mpm;
namespace fs = std::filesystem;

namespace {

std::vector<unsigned char> unbase64(const std::string& s) {
  auto val = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
  };
  std::vector<unsigned char> out;
  unsigned buf = 0;
  int bits = 0;
  for (char c : s) {
    const int v = val(c);
    if (v < 0) continue;
    buf = (buf << 6) | v;
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<unsigned char>((buf >> bits) & 0xff));
    }
  }
  return out;
}

struct Vtu {
  long points = -1, cells = -1;
  std::string header_type;                            // of the byte counts: UInt32 or UInt64
  std::map<std::string, std::vector<double>> arrays;  // every type decoded (Int32, UInt8 fit a double)
  std::map<std::string, int> components;
  std::map<std::string, std::string> formats;         // binary (base64), appended or ascii
};

// `bytes` bytes of `type` values at d.
std::vector<double> decode(const std::string& type, const unsigned char* d, std::uint64_t bytes, const std::string& name) {
  std::vector<double> vals;
  if (type == "Float64") {
    vals.resize(bytes / 8);
    std::memcpy(vals.data(), d, bytes);
  } else if (type == "Int32") {
    for (std::uint64_t k = 0; k + 4 <= bytes; k += 4) {
      std::int32_t x;
      std::memcpy(&x, d + k, 4);
      vals.push_back(x);
    }
  } else if (type == "UInt8") {
    for (std::uint64_t k = 0; k < bytes; ++k) vals.push_back(d[k]);
  } else {
    ADD_FAILURE() << name << ": unexpected type " << type;
  }
  return vals;
}

// A byte count of the header type at p.
std::uint64_t byte_count(const std::string& header_type, const unsigned char* p) {
  if (header_type == "UInt64") {
    std::uint64_t b;
    std::memcpy(&b, p, 8);
    return b;
  }
  std::uint32_t b;
  std::memcpy(&b, p, 4);
  return b;
}

// The XML before <AppendedData> is read with regular expressions; raw appended data from its
// '_' on, each array at its offset: byte count, then the values.
Vtu read_vtu(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string file = ss.str();
  const std::string appended_tag = "<AppendedData encoding=\"raw\">";
  const std::size_t appended_at = file.find(appended_tag);
  const std::string xml = file.substr(0, appended_at);
  Vtu v;
  std::smatch m;
  if (std::regex_search(xml, m, std::regex("NumberOfPoints=\"(\\d+)\" NumberOfCells=\"(\\d+)\""))) {
    v.points = std::stol(m[1]);
    v.cells = std::stol(m[2]);
  }
  if (std::regex_search(xml, m, std::regex("header_type=\"(\\w+)\""))) v.header_type = m[1];
  const std::size_t hsize = v.header_type == "UInt64" ? 8 : 4;
  const std::regex da("<DataArray type=\"(\\w+)\" Name=\"(\\w+)\" NumberOfComponents=\"(\\d+)\" format=\"(\\w+)\"(?: offset=\"(\\d+)\")?(?:/>|>([^<]*)</DataArray>)");
  std::size_t data0 = std::string::npos, data_end = 0;  // raw: the first byte after '_', the last array's end
  if (appended_at != std::string::npos) {
    data0 = file.find('_', appended_at + appended_tag.size());
    EXPECT_NE(data0, std::string::npos);
    ++data0;
  }
  for (auto it = std::sregex_iterator(xml.begin(), xml.end(), da); it != std::sregex_iterator(); ++it) {
    const std::string type = (*it)[1], name = (*it)[2], fmt = (*it)[4], body = (*it)[6];
    v.components[name] = std::stoi((*it)[3]);
    v.formats[name] = fmt;
    std::vector<double> vals;
    if (fmt == "ascii") {
      // every token must be a number (an 8-bit type written as a character would not be)
      std::istringstream is(body);
      std::string tok;
      while (is >> tok) {
        size_t used = 0;
        vals.push_back(std::stod(tok, &used));
        EXPECT_EQ(used, tok.size()) << name << ": '" << tok << "'";
      }
    } else if (fmt == "appended") {
      EXPECT_NE(data0, std::string::npos) << name << ": no raw AppendedData";
      const std::size_t at = data0 + std::stoull((*it)[5]);
      if (at + hsize > file.size()) {
        ADD_FAILURE() << name << ": offset past the end of the file";
        continue;
      }
      const auto* p = reinterpret_cast<const unsigned char*>(file.data() + at);
      const std::uint64_t bytes = byte_count(v.header_type, p);
      if (at + hsize + bytes > file.size()) {
        ADD_FAILURE() << name << ": " << bytes << " bytes past the end of the file";
        continue;
      }
      vals = decode(type, p + hsize, bytes, name);
      data_end = std::max(data_end, at + hsize + static_cast<std::size_t>(bytes));
    } else {
      const std::vector<unsigned char> raw = unbase64(body);
      if (raw.size() < hsize) {
        ADD_FAILURE() << name << ": no byte count";
        continue;
      }
      const std::uint64_t bytes = byte_count(v.header_type, raw.data());
      EXPECT_EQ(bytes + hsize, raw.size()) << name;
      vals = decode(type, raw.data() + hsize, std::min<std::uint64_t>(bytes, raw.size() - hsize), name);
    }
    v.arrays[name] = vals;
  }
  if (appended_at != std::string::npos)  // the arrays fill the appended data up to its end tag
    EXPECT_EQ(file.substr(data_end), "\n  </AppendedData>\n</VTKFile>\n") << path;
  return v;
}

std::string write_tmp(const std::string& name, const std::string& text) {
  const fs::path p = fs::temp_directory_path() / ("granflow_mpm_test_" + name + ".toml");
  std::ofstream(p) << text;
  return p.string();
}

const char* kGood = R"(
name = "tiny"
[grid]
origin = [0.0, 0.0]
size = [0.4, 0.2]
h = 0.02
[particles]
per_cell = 4
[time]
dt = 1e-4
[material]
parameters = "column_collapse"
model = "frictional"
[[body]]
min = [0.0, 0.0]
max = [0.1, 0.1]
[[wall]]
side = "x-"
type = "free_slip"
[[wall]]
side = "y-"
[[stage]]
duration = 0.002
[output]
times = [0.001]
)";

std::string load_error(const std::string& name, const std::string& text) {
  try {
    const Scene sc = mpm::load_scene(write_tmp(name, text));
    make_setup(sc);
  } catch (const io::InputError& e) {
    return e.what();
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

std::string replace(std::string s, const std::string& a, const std::string& b) {
  const auto p = s.find(a);
  EXPECT_NE(p, std::string::npos) << a;
  return s.replace(p, a.size(), b);
}

// A frame of known values, every array, an odd count (no array a multiple of 8 bytes), values
// that need all 64 bits (1/3, -0, 1e300) and no NaN; `dim` 2 leaves z = 0 in the file.
Frame known_frame(int dim) {
  Frame f;
  f.n = 7;
  f.dim = dim;
  int k = 0;
  auto fill = [&](std::vector<double>& v, long size) {
    v.resize(size);
    for (long i = 0; i < size; ++i, ++k) v[i] = (k % 2 ? -1.0 : 1.0) * (k + 1) / 3.0 * std::pow(10.0, k % 7 - 3);
  };
  fill(f.x, dim * f.n);
  fill(f.v, dim * f.n);
  for (auto* a : {&f.T, &f.p, &f.q, &f.eps_pd, &f.eta_c, &f.K_col, &f.e, &f.sxx, &f.syy, &f.sxy}) fill(*a, f.n);
  f.p[0] = 2e-300 / 3;
  f.q[1] = -0.0;
  f.T[2] = 1e300;
  f.material = {0, 1, 2, 0, 1, 2, 0};
  f.body = {6, 5, 4, 3, 2, 1, -1};
  return f;
}

// What each array of the frame must hold in the file (components interleaved, z = 0 in 2D).
std::map<std::string, std::vector<double>> expected_arrays(const Frame& f) {
  auto interleaved = [&](const std::vector<double>& a) {
    std::vector<double> o(3 * f.n, 0.0);
    for (long i = 0; i < f.n; ++i)
      for (int d = 0; d < f.dim; ++d) o[3 * i + d] = a[d * f.n + i];
    return o;
  };
  std::map<std::string, std::vector<double>> e = {
      {"position", interleaved(f.x)}, {"velocity", interleaved(f.v)}, {"p", f.p},   {"q", f.q},
      {"eps_pd", f.eps_pd},           {"T", f.T},                     {"eta_c", f.eta_c}, {"K_col", f.K_col},
      {"e", f.e},                     {"sigma_xx", f.sxx},            {"sigma_yy", f.syy}, {"sigma_xy", f.sxy}};
  for (long i = 0; i < f.n; ++i) {
    e["connectivity"].push_back(i);
    e["offsets"].push_back(i + 1);
    e["types"].push_back(1);
    e["material"].push_back(f.material[i]);
    e["body"].push_back(f.body[i]);
  }
  return e;
}

bool identical_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

// The frame written in each format to dir/frame_<format>.vtu.
std::map<std::string, fs::path> write_formats(const Frame& f, const fs::path& dir) {
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::map<std::string, fs::path> files;
  for (const auto& [name, format] : {std::pair<const char*, FrameFormat>{"raw", FrameFormat::Raw},
                                     {"base64", FrameFormat::Base64}, {"ascii", FrameFormat::Ascii}}) {
    files[name] = dir / ("frame_" + std::string(name) + ".vtu");
    write_vtu(files[name].string(), f, format);
  }
  return files;
}

}  // namespace

TEST(MpmIo, VtuReadBackMatchesFrame) {
  for (const FrameFormat format : {FrameFormat::Raw, FrameFormat::Base64, FrameFormat::Ascii}) {
    SCOPED_TRACE(static_cast<int>(format));
    Scene sc = mpm::load_scene(write_tmp("good", kGood));
    sc.output.format = format;
    const SceneSetup su = make_setup(sc);
    auto r = make_cpu_runner(su);
    const fs::path out = fs::temp_directory_path() / ("granflow_mpm_vtu_" + std::to_string(static_cast<int>(format)));
    fs::remove_all(out);
    RunOptions opt;
    opt.out_dir = out.string();
    opt.progress = false;
    const RunSummary s = run(su, *r, opt);
    ASSERT_TRUE(s.ok) << s.message;
    Frame f;
    r->frame(f, true);
    ASSERT_TRUE(fs::exists(out / "frames.pvd"));
    for (const char* csv : {"runout.csv", "tracked.csv", "profile_final.csv"}) EXPECT_TRUE(fs::exists(out / csv));
    std::vector<fs::path> vtus;
    for (const auto& e : fs::directory_iterator(out)) {
      EXPECT_NE(e.path().extension(), ".tmp");
      if (e.path().extension() == ".vtu") vtus.push_back(e.path());
    }
    std::sort(vtus.begin(), vtus.end());
    ASSERT_GE(vtus.size(), 3u);  // t = 0, t = 0.001, final
    const Vtu v = read_vtu(vtus.back().string());
    EXPECT_EQ(v.points, f.n);
    EXPECT_EQ(v.cells, f.n);
    for (const char* name : {"position", "velocity", "p", "q", "eps_pd", "T", "eta_c", "K_col"})
      ASSERT_TRUE(v.arrays.count(name)) << name;
    EXPECT_EQ(v.components.at("position"), 3);
    ASSERT_EQ(v.arrays.at("position").size(), static_cast<size_t>(3 * f.n));
    // vertex cells: connectivity 0..n-1, offsets 1..n, every type VTK_VERTEX (1)
    ASSERT_EQ(v.arrays.at("connectivity").size(), static_cast<size_t>(f.n));
    ASSERT_EQ(v.arrays.at("offsets").size(), static_cast<size_t>(f.n));
    ASSERT_EQ(v.arrays.at("types").size(), static_cast<size_t>(f.n));
    for (long i = 0; i < f.n; ++i) {
      EXPECT_EQ(v.arrays.at("connectivity")[i], i);
      EXPECT_EQ(v.arrays.at("offsets")[i], i + 1);
      EXPECT_EQ(v.arrays.at("types")[i], 1);
    }
    ASSERT_EQ(v.arrays.at("p").size(), static_cast<size_t>(f.n));
    for (long i = 0; i < f.n; i += 7) {
      EXPECT_NEAR(v.arrays.at("position")[3 * i + 1], f.x[f.n + i], 1e-9);
      EXPECT_NEAR(v.arrays.at("p")[i], f.p[i], 1e-9 * (1 + std::fabs(f.p[i])));
    }
    // the PVD lists every frame
    std::ifstream pvd(out / "frames.pvd");
    std::stringstream ss;
    ss << pvd.rdbuf();
    for (const auto& p : vtus) EXPECT_NE(ss.str().find(p.filename().string()), std::string::npos);
  }
}

// Raw appended and base64 hold the frame's values bit for bit; ASCII to its 10 digits.
TEST(MpmIo, RawAndBase64FramesHoldEveryBit) {
  for (const int dim : {2, 3}) {
    SCOPED_TRACE(dim);
    const Frame f = known_frame(dim);
    const auto expected = expected_arrays(f);
    const auto files = write_formats(f, fs::temp_directory_path() / "granflow_mpm_formats");
    const Vtu raw = read_vtu(files.at("raw").string()), b64 = read_vtu(files.at("base64").string()),
              txt = read_vtu(files.at("ascii").string());
    EXPECT_EQ(raw.header_type, "UInt64");
    EXPECT_EQ(b64.header_type, "UInt32");
    for (const Vtu* v : {&raw, &b64, &txt}) {
      EXPECT_EQ(v->points, f.n);
      EXPECT_EQ(v->cells, f.n);
      EXPECT_EQ(v->arrays.size(), expected.size());
    }
    for (const auto& [name, want] : expected) {
      SCOPED_TRACE(name);
      ASSERT_TRUE(raw.arrays.count(name) && b64.arrays.count(name) && txt.arrays.count(name));
      EXPECT_EQ(raw.formats.at(name), "appended");
      EXPECT_EQ(b64.formats.at(name), "binary");
      EXPECT_TRUE(identical_bits(raw.arrays.at(name), want));
      EXPECT_TRUE(identical_bits(b64.arrays.at(name), want));
      ASSERT_EQ(txt.arrays.at(name).size(), want.size());
      for (size_t i = 0; i < want.size(); ++i) EXPECT_NEAR(txt.arrays.at(name)[i], want[i], 1e-9 * std::fabs(want[i]));
    }
  }
}

// scripts/plot_mpm.py's reader (read_vtu) gives the same bits from the raw and base64 files: its
// Float64 arrays printed as hexadecimal floats by the system python3 with numpy.
TEST(MpmIo, PlotScriptReadsRawAndBase64FramesBitForBit) {
  const std::string py = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
  const Frame f = known_frame(2);
  const auto expected = expected_arrays(f);
  const auto files = write_formats(f, fs::temp_directory_path() / "granflow_mpm_formats_py");
  const fs::path snippet = fs::temp_directory_path() / "granflow_mpm_formats_py" / "read.py";
  std::ofstream(snippet) << "import sys\n"
                            "try:\n    import numpy as np\nexcept ImportError:\n    sys.exit(77)\n"
                            "sys.path.insert(0, sys.argv[1])\n"
                            "import plot_mpm\n"
                            "for path in sys.argv[2:]:\n"
                            "    for name, a in sorted(plot_mpm.read_vtu(path, np).items()):\n"
                            "        if name != 'speed':\n"
                            "            print(path, name, ' '.join(float(x).hex() for x in np.asarray(a).T.ravel()))\n";
  const std::string cmd = py + " '" + snippet.string() + "' '" GRANFLOW_SOURCE_DIR "/scripts' '" +
                          files.at("raw").string() + "' '" + files.at("base64").string() + "'";
  FILE* p = ::popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  std::string out;
  char buf[4096];
  for (std::size_t k; (k = std::fread(buf, 1, sizeof buf, p)) > 0;) out.append(buf, k);
  const int status = ::pclose(p);
  if (WIFEXITED(status) && WEXITSTATUS(status) == 77) GTEST_SKIP() << py << " has no numpy";
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << cmd << "\n" << out;
  std::map<std::string, std::map<std::string, std::vector<double>>> read;  // file -> name -> values
  std::istringstream is(out);
  for (std::string line; std::getline(is, line);) {
    std::istringstream ls(line);
    std::string path, name, tok;
    ls >> path >> name;
    std::vector<double>& vals = read[path][name];
    while (ls >> tok) vals.push_back(std::strtod(tok.c_str(), nullptr));
  }
  for (const char* format : {"raw", "base64"}) {
    SCOPED_TRACE(format);
    const auto& arrays = read[files.at(format).string()];
    EXPECT_EQ(arrays.size(), 12u);  // the Float64 arrays
    for (const auto& [name, vals] : arrays) EXPECT_TRUE(identical_bits(vals, expected.at(name))) << name;
  }
}

TEST(MpmIo, BadScenesGiveClearErrors) {
  const std::string good = kGood;
  EXPECT_EQ(load_error("ok", good), "");
  const std::pair<std::string, std::string> cases[] = {
      {replace(good, "h = 0.02", "h = 0.02\nspacing = 3"), "unknown key 'grid.spacing'"},
      {replace(good, "max = [0.1, 0.1]", "max = [0.1, 0.5]"), "outside the grid"},
      {replace(good, "dt = 1e-4", "dt = 1e-2"), "time.dt"},
      {replace(good, "per_cell = 4", "per_cell = 3"), "particles.per_cell"},
      {replace(good, "model = \"frictional\"", "model = \"viscous\""), "material.model"},
      {replace(good, "side = \"y-\"", "side = \"x-\""), "contradicts"},
      {replace(good, "duration = 0.002", "duration = 0.002\n[stage.gate]\npoint = [0.1, 0]\nnormal = [1, 1]"),
       "stage[0].gate.hold"},
      {replace(good, "min = [0.0, 0.0]", "min = [0.0]"), "body[0].min"},
      {replace(good, "times = [0.001]", "times = [0.5]"), "output.times"},
      {replace(good, "[particles]", "[particle]"), "particle"},
  };
  for (const auto& [text, expect] : cases) {
    const std::string err = load_error("bad", text);
    EXPECT_NE(err.find(expect), std::string::npos) << "expected '" << expect << "' in: " << err;
  }
}

// Friction and lifting gates: the keys are read, and a bad value names the file, its line and
// the key.
TEST(MpmIo, BoundaryKeysAreReadAndCheckedWithFileLineAndKey) {
  const std::string good = replace(replace(kGood, "side = \"y-\"", "side = \"y-\"\nmu = 0.3"),
                                   "duration = 0.002",
                                   "duration = 0.002\n[stage.gate]\npoint = [0.1, 0]\nnormal = [1, 0]\nlift_speed = 0.5");
  const Scene sc = mpm::load_scene(write_tmp("friction", good));
  ASSERT_EQ(sc.walls.size(), 2u);
  EXPECT_FALSE(sc.walls[0].mu.has_value());  // free_slip
  ASSERT_TRUE(sc.walls[1].mu.has_value());   // mu alone: frictional
  EXPECT_EQ(*sc.walls[1].mu, 0.3);
  ASSERT_TRUE(sc.stages[0].gate.has_value());
  EXPECT_EQ(sc.stages[0].gate->lift_speed, 0.5);
  EXPECT_EQ(load_error("friction_ok", good), "");
  const std::string base = replace(kGood, "[[stage]]", "[base]\nx = [0.0, 0.4]\ny = [0.0, 0.0]\nmu = 0.2\n\n[[stage]]");
  ASSERT_TRUE(mpm::load_scene(write_tmp("base_mu", base)).base->mu.has_value());

  // line of the offending key in the text (1-based)
  auto line_of = [](const std::string& text, const std::string& key) {
    const size_t p = text.find(key);
    EXPECT_NE(p, std::string::npos) << key;
    return 1 + std::count(text.begin(), text.begin() + static_cast<long>(p), '\n');
  };
  struct Bad {
    std::string text, key, expect, line_key;
  };
  const Bad cases[] = {
      {replace(kGood, "side = \"y-\"", "side = \"y-\"\nmu = -0.1"), "wall[1].mu", "must be >= 0", "mu = -0.1"},
      {replace(kGood, "side = \"y-\"", "side = \"y-\"\ntype = \"frictional\"\nmu = -1"), "wall[1].mu", ">= 0",
       "mu = -1"},
      {replace(kGood, "side = \"y-\"", "side = \"y-\"\ntype = \"frictional\""), "wall[1].mu", "required", "[[wall]]\nside = \"y-\""},
      {replace(kGood, "type = \"free_slip\"", "type = \"free_slip\"\nmu = 0.3"), "wall[0].mu",
       "friction needs type = \"frictional\"", "mu = 0.3"},
      {replace(base, "mu = 0.2", "mu = -0.2"), "base.mu", "must be >= 0", "mu = -0.2"},
      {replace(good, "lift_speed = 0.5", "lift_speed = 0"), "stage[0].gate.lift_speed", "must be > 0", "lift_speed = 0"},
      {replace(good, "lift_speed = 0.5", "lift_speed = -1"), "stage[0].gate.lift_speed", "must be > 0", "lift_speed = -1"},
      {replace(replace(good, "normal = [1, 0]", "normal = [1, 1]\nhold = \"all\""), "point = [0.1, 0]", "point = [0.1, 0.1]"),
       "stage[0].gate.lift_speed", "no y component", "lift_speed = 0.5"},
  };
  for (const Bad& c : cases) {
    const std::string err = load_error("bad_boundary", c.text);
    const std::string file = write_tmp("bad_boundary", c.text);
    const std::string at = file + ":" + std::to_string(line_of(c.text, c.line_key));
    EXPECT_NE(err.find(at), std::string::npos) << "expected '" << at << "' in: " << err;
    EXPECT_NE(err.find("'" + c.key + "'"), std::string::npos) << "expected '" << c.key << "' in: " << err;
    EXPECT_NE(err.find(c.expect), std::string::npos) << "expected '" << c.expect << "' in: " << err;
  }

  // scenes built in code are checked by make_setup (keys without a file)
  Scene in_code = mpm::load_scene(write_tmp("friction", good));
  in_code.walls[1].mu = -0.5;
  EXPECT_THROW(make_setup(in_code), SceneError);
  in_code = mpm::load_scene(write_tmp("friction", good));
  for (int k = 0; k < 6; ++k) in_code.walls.push_back(in_code.walls[1]);  // 7 frictional walls
  EXPECT_THROW(make_setup(in_code), SceneError);
  in_code = mpm::load_scene(write_tmp("friction", good));
  in_code.stages[0].gate->normal = {1.0, 0.5};
  in_code.stages[0].gate->normal_only = false;
  try {
    make_setup(in_code);
    ADD_FAILURE() << "an inclined lifting gate was accepted";
  } catch (const SceneError& e) {
    EXPECT_EQ(e.key(), "stage[0].gate.lift_speed");
  }
}

TEST(MpmIo, ParticleLeavingTheGridStopsWithMessageAndLastGoodFrame) {
  Scene sc = mpm::load_scene(write_tmp("leave", kGood));
  sc.walls.clear();  // nothing holds the block: it falls out of the grid
  sc.stages[0].duration = 0.5;
  sc.output.times.clear();
  sc.output.series_dt = 0.01;
  const SceneSetup su = make_setup(sc);
  auto r = make_cpu_runner(su);
  const fs::path out = fs::temp_directory_path() / "granflow_mpm_leave";
  fs::remove_all(out);
  RunOptions opt;
  opt.out_dir = out.string();
  opt.progress = false;
  const RunSummary s = run(su, *r, opt);
  ASSERT_FALSE(s.ok);
  EXPECT_NE(s.message.find("particle "), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("position (left the grid)"), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("at step "), std::string::npos) << s.message;
  bool last_good = false;
  for (const auto& e : fs::directory_iterator(out))
    if (e.path().filename().string().find("_last_good.vtu") != std::string::npos) last_good = true;
  EXPECT_TRUE(last_good);
  EXPECT_TRUE(fs::exists(out / "runout.csv"));
}

TEST(MpmIo, GeostaticInitialStressLiesOnTheYieldSurface) {
  const Scene sc = mpm::load_scene(write_tmp("geo", replace(kGood, "[[body]]", "[initial_stress]\nkind = \"geostatic\"\nK0 = 0.6\n\n[[body]]")));
  ASSERT_TRUE(sc.initial.geostatic);
  const SceneSetup su = make_setup(sc);
  const HostParticles& hp = su.particles;
  const long n = hp.n;
  const double rho0 = sc.material.params.c.rho_p / (1 + sc.material.e0);
  for (long i = 0; i < n; ++i) {
    const double depth = 0.1 - hp.x[n + i];
    EXPECT_NEAR(hp.sig[n + i], -rho0 * 9.81 * depth, 1e-9 * rho0 * 9.81);        // sigma_yy
    EXPECT_NEAR(hp.sig[i], 0.6 * hp.sig[n + i], 1e-12 * rho0);                  // sigma_xx = K0 sigma_yy
    Mat3<double> s = Mat3<double>::Zero();
    s(0, 0) = hp.sig[i];
    s(1, 1) = hp.sig[n + i];
    s(2, 2) = hp.sig[2 * n + i];
    EXPECT_GT(hp.eps[i], 0.0);
    EXPECT_NEAR((yield_function<LodeShape::SmoothMohrCoulomb>(sc.material.params.f, s, hp.eps[i], sc.material.e0)), 0.0, 1e-9);
  }
}
