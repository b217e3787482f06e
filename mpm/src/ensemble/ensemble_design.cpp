#include <granflow/mpm/ensemble_design.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <granflow/io/input_error.hpp>
#include <granflow/io/toml_reader.hpp>

namespace granflow::mpm {
using namespace granflow::io;  // the strict TOML reader this file format is built on
namespace {

// new-joe-kuo-6.21201 (Joe & Kuo 2008), dimensions 2-21: degree s of the primitive polynomial,
// its inner coefficients a, initial direction numbers m_1..m_s. Dimension 1 is van der Corput.
struct SobolDim {
  unsigned s, a;
  std::array<std::uint32_t, 7> m;
};
constexpr SobolDim kJoeKuo[kMaxQuasiRandomDims - 1] = {
    {1, 0, {1}},                        // 2
    {2, 1, {1, 3}},                     // 3
    {3, 1, {1, 3, 1}},                  // 4
    {3, 2, {1, 1, 1}},                  // 5
    {4, 1, {1, 1, 3, 3}},               // 6
    {4, 4, {1, 3, 5, 13}},              // 7
    {5, 2, {1, 1, 5, 5, 17}},           // 8
    {5, 4, {1, 1, 5, 5, 5}},            // 9
    {5, 7, {1, 1, 7, 11, 19}},          // 10
    {5, 11, {1, 1, 5, 1, 1}},           // 11
    {5, 13, {1, 1, 1, 3, 11}},          // 12
    {5, 14, {1, 3, 5, 5, 31}},          // 13
    {6, 1, {1, 3, 3, 9, 7, 49}},        // 14
    {6, 13, {1, 1, 1, 15, 21, 21}},     // 15
    {6, 16, {1, 3, 1, 13, 27, 49}},     // 16
    {6, 19, {1, 1, 1, 15, 7, 5}},       // 17
    {6, 22, {1, 3, 1, 15, 13, 25}},     // 18
    {6, 25, {1, 1, 5, 5, 19, 61}},      // 19
    {7, 1, {1, 3, 7, 11, 23, 15, 103}}, // 20
    {7, 4, {1, 3, 7, 13, 13, 15, 69}},  // 21
};

constexpr unsigned kPrimes[kMaxQuasiRandomDims] = {2,  3,  5,  7,  11, 13, 17, 19, 23, 29, 31,
                                                   37, 41, 43, 47, 53, 59, 61, 67, 71, 73};

// Direction numbers V_1..V_32 (V_k = m_k 2^(32-k)) of dimension d (0-based).
std::array<std::uint32_t, 32> directions(int d) {
  std::array<std::uint32_t, 32> v{};
  if (d == 0) {
    for (unsigned k = 0; k < 32; ++k) v[k] = 1u << (31 - k);
    return v;
  }
  const SobolDim& p = kJoeKuo[d - 1];
  for (unsigned k = 0; k < p.s; ++k) v[k] = p.m[k] << (31 - k);
  for (unsigned k = p.s; k < 32; ++k) {
    v[k] = v[k - p.s] ^ (v[k - p.s] >> p.s);
    for (unsigned j = 1; j < p.s; ++j)
      if ((p.a >> (p.s - 1 - j)) & 1u) v[k] ^= v[k - j];
  }
  return v;
}

void check_points(long n, int dims, long skip, int max_dims, const char* who) {
  if (n < 1 || dims < 1 || dims > max_dims || skip < 0 || skip > (1L << 32) - n)
    throw std::invalid_argument(std::string(who) + ": need n >= 1, 1 <= dims <= " + std::to_string(max_dims) +
                                ", 0 <= skip, skip + n <= 2^32");
}

// Cranley-Patterson rotation: every coordinate d moves by s_d from mt19937_64(seed), mod 1.
void random_shift(std::vector<std::vector<double>>& u, int dims, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<double> s(dims);
  for (double& x : s) x = unit_double(rng());
  for (auto& p : u)
    for (int d = 0; d < dims; ++d) {
      const double v = p[d] + s[d];
      p[d] = v >= 1.0 ? v - 1.0 : v;
    }
}

// A key as `granflow mpm --set` takes it (mpm/src/scene/scene_file.cpp split_key): names of letters,
// digits, _ and -, joined by '.', a name may carry an index [i]; the last part is a name.
// NAME:KEY names the [[material]] a key is of (NAME: letters, digits, _ and -).
// Returns the key with indices written without leading zeros, or "" when malformed.
std::string canonical_set_key(const std::string& key) {
  std::string out;
  std::size_t at = 0;
  if (const std::size_t colon = key.find(':'); colon != std::string::npos) {
    if (colon == 0) return "";
    for (std::size_t i = 0; i < colon; ++i)
      if (!std::isalnum(static_cast<unsigned char>(key[i])) && key[i] != '_' && key[i] != '-') return "";
    out = key.substr(0, colon + 1);
    at = colon + 1;
  }
  for (;;) {
    std::size_t end = at;
    while (end < key.size() && (std::isalnum(static_cast<unsigned char>(key[end])) || key[end] == '_' || key[end] == '-'))
      ++end;
    if (end == at) return "";
    out += key.substr(at, end - at);
    if (end < key.size() && key[end] == '[') {
      const std::size_t close = key.find(']', end);
      const std::string digits = close == std::string::npos ? "" : key.substr(end + 1, close - end - 1);
      if (digits.empty() || digits.size() > 6 || digits.find_first_not_of("0123456789") != std::string::npos) return "";
      out += "[" + std::to_string(std::stol(digits)) + "]";
      end = close + 1;
      if (end == key.size()) return "";  // ends in an index: --set changes values, not entries
    }
    if (end == key.size()) return out;
    if (key[end] != '.') return "";
    out += '.';
    at = end + 1;
  }
}

std::string number_text(double x) {
  std::ostringstream os;
  os << x;
  return os.str();
}

// u in [0, 1] to [lo, hi], uniform in the value or (log_scale) in its logarithm; exact at u = 0, 1.
double from_unit(const DesignVariable& v, double u) {
  if (u <= 0) return v.lo;
  if (u >= 1) return v.hi;
  const double x = v.log_scale ? std::exp((1 - u) * std::log(v.lo) + u * std::log(v.hi)) : (1 - u) * v.lo + u * v.hi;
  return std::clamp(x, v.lo, v.hi);
}

// range = [lo, hi]: two numbers; lo < hi unless equal_ok; above 0 with scale = "log".
void read_range(TomlTable& t, DesignVariable& v, bool equal_ok) {
  if (!t.has("range")) t.fail_missing("range", "[lo, hi]");  // names a similar key: a typo?
  const std::vector<double> r = t.numbers("range", Bounds::any(), false);
  if (r.size() != 2) t.fail("range", "needs two numbers [lo, hi], got " + std::to_string(r.size()));
  v.lo = r[0];
  v.hi = r[1];
  if (!(v.lo < v.hi) && !(equal_ok && v.lo == v.hi))
    t.fail("range", "empty range: lo must be below hi, got [" + number_text(v.lo) + ", " + number_text(v.hi) + "]");
  v.log_scale = t.choice("scale", {"linear", "log"}, "linear") == "log";
  if (v.log_scale && !(v.lo > 0))
    t.fail("range", "scale = \"log\" needs a range above 0, got [" + number_text(v.lo) + ", " + number_text(v.hi) + "]");
}

EnsembleDesign read_design(const toml::table& doc, const std::string& file) {
  TomlTable root(doc, file);
  EnsembleDesign d;
  d.file = file;

  TomlTable design = root.table("design");
  d.method = design.choice("method", {"list", "grid", "lhs", "sobol", "halton"}, "");
  const bool quasi = d.method == "sobol" || d.method == "halton";
  const bool sampled = quasi || d.method == "lhs";
  const std::string with = "with method = \"" + d.method + "\"";
  if (sampled) {
    d.members = design.integer("members", 1, kMaxDesignMembers);
  } else if (design.has("members")) {
    design.fail("members", "not allowed " + with + ": the members are " +
                               (d.method == "list" ? "the entries of the values lists" : "all combinations of the levels"));
  }
  if (quasi)
    d.scramble = design.boolean_or("scramble", false);
  else if (design.has("scramble"))
    design.fail("scramble", "only with method = \"sobol\" or \"halton\" (a random shift of the points)");
  if (d.method == "lhs" || d.scramble)
    d.seed = static_cast<std::uint64_t>(design.integer_or("seed", 1, 0, std::numeric_limits<long>::max()));
  else if (design.has("seed"))
    design.fail("seed", quasi ? "seeds the random shift: needs scramble = true" : "not used " + with + " (nothing is drawn)");
  design.finish();

  auto tables = root.array_of_tables("vary");
  if (tables.empty()) root.fail("vary", "at least one [[vary]] table (a key and its values or range) is required");
  std::vector<std::string> canonical;
  if (!sampled) d.members = 1;
  for (auto& t : tables) {
    DesignVariable v;
    v.line = t.line();
    v.key = t.string("key");
    const std::string key = canonical_set_key(v.key);
    if (key.empty())
      t.fail("key", "'" + v.key + "' is not a --set key: names of letters, digits, _ and - joined by '.', "
                    "with [i] for an entry of an array of tables (e.g. stage[1].gate.lift_speed) and NAME: "
                    "before a key of the [[material]] named NAME (e.g. weak:frictional.phi_c_deg)");
    for (std::size_t j = 0; j < canonical.size(); ++j)
      if (canonical[j] == key)
        t.fail("key", "'" + v.key + "' is varied twice: also in the [[vary]] at line " + std::to_string(d.vary[j].line));
    if (quasi && d.vary.size() == static_cast<std::size_t>(kMaxQuasiRandomDims))
      t.fail("key", with + " at most " + std::to_string(kMaxQuasiRandomDims) + " variables can vary");

    auto refuse = [&](const char* k, const std::string& why) {
      if (t.has(k)) t.fail(k, why);
    };
    if (d.method == "list") {
      for (const char* k : {"range", "count", "scale"}) refuse(k, "not used " + with + ": values are the members' values");
      if (!t.has("values")) t.fail_missing("values", "one number per member");
      v.values = t.numbers("values", Bounds::any(), false);
      if (d.vary.empty()) {
        if (static_cast<long>(v.values.size()) > kMaxDesignMembers)
          t.fail("values", "more than " + std::to_string(kMaxDesignMembers) + " members");
        d.members = static_cast<long>(v.values.size());
      } else if (static_cast<long>(v.values.size()) != d.members) {
        t.fail("values", "'" + v.key + "' has " + std::to_string(v.values.size()) + " values, '" + d.vary[0].key +
                             "' (line " + std::to_string(d.vary[0].line) + ") has " + std::to_string(d.members) +
                             ": with method = \"list\" every [[vary]] gives one value per member");
      }
    } else if (d.method == "grid") {
      if (t.has("values")) {
        for (const char* k : {"range", "count", "scale"}) refuse(k, "give either values (the levels) or range and count");
        v.values = t.numbers("values", Bounds::any(), false);
      } else {
        if (!t.has("range") && !t.has("count"))
          t.fail("values", "required " + with + ": values (the levels) or range and count");
        v.count = t.integer("count", 1, kMaxDesignMembers);
        read_range(t, v, v.count == 1);
        if (v.count == 1 && v.lo != v.hi)
          t.fail("count", "count = 1 is one level: needs lo == hi, got [" + number_text(v.lo) + ", " +
                              number_text(v.hi) + "]");
        for (long i = 0; i < v.count; ++i)
          v.values.push_back(v.count == 1 ? v.lo : from_unit(v, static_cast<double>(i) / static_cast<double>(v.count - 1)));
      }
      if (d.members * static_cast<long>(v.values.size()) > kMaxDesignMembers)
        t.fail(t.has("values") ? "values" : "count", "the grid would have more than " + std::to_string(kMaxDesignMembers) +
                                                         " members (the product of the numbers of levels)");
      d.members *= static_cast<long>(v.values.size());
    } else {
      for (const char* k : {"values", "count"}) refuse(k, "not used " + with + ": give range = [lo, hi]");
      read_range(t, v, false);
    }
    t.finish();
    canonical.push_back(key);
    d.vary.push_back(v);
  }
  root.finish();

  // Sampling
  const int D = static_cast<int>(d.vary.size());
  d.values.assign(d.members, std::vector<double>(D));
  if (d.method == "list") {
    for (long i = 0; i < d.members; ++i)
      for (int j = 0; j < D; ++j) d.values[i][j] = d.vary[j].values[i];
  } else if (d.method == "grid") {  // row-major: the first [[vary]] varies slowest
    for (long i = 0; i < d.members; ++i) {
      long rest = i;
      for (int j = D - 1; j >= 0; --j) {
        const long levels = static_cast<long>(d.vary[j].values.size());
        d.values[i][j] = d.vary[j].values[rest % levels];
        rest /= levels;
      }
    }
  } else {
    std::vector<std::vector<double>> u = d.method == "lhs"     ? latin_hypercube(d.members, D, d.seed)
                                         : d.method == "sobol" ? sobol_points(d.members, D)
                                                               : halton_points(d.members, D);
    if (d.scramble) random_shift(u, D, d.seed);
    for (long i = 0; i < d.members; ++i)
      for (int j = 0; j < D; ++j) d.values[i][j] = from_unit(d.vary[j], u[i][j]);
  }
  return d;
}

}  // namespace

double unit_double(std::uint64_t bits) { return static_cast<double>(bits >> 11) * 0x1.0p-53; }

std::uint64_t uniform_below(std::mt19937_64& rng, std::uint64_t bound) {
  if (bound == 0) throw std::invalid_argument("uniform_below: bound must be >= 1");
  // 2^64 mod bound: below it, r % bound would favour the small results
  const std::uint64_t threshold = (std::uint64_t{0} - bound) % bound;
  for (;;) {
    const std::uint64_t r = rng();
    if (r >= threshold) return r % bound;
  }
}

double radical_inverse(std::uint64_t i, unsigned base) {
  if (base < 2) throw std::invalid_argument("radical_inverse: base must be >= 2");
  std::uint64_t num = 0, den = 1;
  for (; i > 0; i /= base) {
    if (den > (std::uint64_t{1} << 53) / base) throw std::invalid_argument("radical_inverse: index too large");
    num = num * base + i % base;
    den *= base;
  }
  return static_cast<double>(num) / static_cast<double>(den);
}

std::vector<std::vector<double>> latin_hypercube(long n, int dims, std::uint64_t seed) {
  if (n < 1 || dims < 1) throw std::invalid_argument("latin_hypercube: need n >= 1 and dims >= 1");
  std::mt19937_64 rng(seed);
  std::vector<std::vector<double>> x(n, std::vector<double>(dims));
  std::vector<long> perm(n);
  const double N = static_cast<double>(n);
  for (int d = 0; d < dims; ++d) {
    for (long i = 0; i < n; ++i) perm[i] = i;
    for (long i = n - 1; i > 0; --i) std::swap(perm[i], perm[uniform_below(rng, static_cast<std::uint64_t>(i) + 1)]);
    for (long i = 0; i < n; ++i) {
      const double s = static_cast<double>(perm[i]);
      const double upper = (s + 1) / N;
      const double v = (s + unit_double(rng())) / N;  // >= fl(s / N): rounding is monotonic
      x[i][d] = v < upper ? v : std::nextafter(upper, 0.0);
    }
  }
  return x;
}

std::vector<std::vector<double>> sobol_points(long n, int dims, long skip) {
  check_points(n, dims, skip, kMaxQuasiRandomDims, "sobol_points");
  std::vector<std::vector<double>> x(n, std::vector<double>(dims));
  for (int d = 0; d < dims; ++d) {
    const auto v = directions(d);
    for (long i = 0; i < n; ++i) {
      const std::uint64_t index = static_cast<std::uint64_t>(skip + i);
      std::uint64_t gray = index ^ (index >> 1);  // Gray-code order, as Joe & Kuo's generator
      std::uint32_t bits = 0;
      for (unsigned k = 0; gray; ++k, gray >>= 1)
        if (gray & 1u) bits ^= v[k];
      x[i][d] = static_cast<double>(bits) * 0x1.0p-32;
    }
  }
  return x;
}

std::vector<std::vector<double>> halton_points(long n, int dims, long skip) {
  check_points(n, dims, skip, kMaxQuasiRandomDims, "halton_points");
  std::vector<std::vector<double>> x(n, std::vector<double>(dims));
  for (long i = 0; i < n; ++i)
    for (int d = 0; d < dims; ++d) x[i][d] = radical_inverse(static_cast<std::uint64_t>(skip + i), kPrimes[d]);
  return x;
}

EnsembleDesign load_design(const std::string& path) { return read_design(TomlTable::parse_file(path), path); }

EnsembleDesign parse_design(const std::string& toml_text, const std::string& name) {
  return read_design(TomlTable::parse_text(toml_text, name), name);
}

std::string format_exact(double v) {
  // The fewest significant digits (15 to 17) that read back to the same double (snprintf, not
  // std::to_chars: the GPU machine's host compiler may predate floating-point to_chars; the
  // program keeps the C locale).
  char buf[40];
  for (int digits = 15; digits < 17; ++digits) {
    std::snprintf(buf, sizeof buf, "%.*g", digits, v);
    if (std::strtod(buf, nullptr) == v) return buf;
  }
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::vector<std::string> member_overrides(const EnsembleDesign& d, long member) {
  if (member < 0 || member >= static_cast<long>(d.values.size()))
    throw std::out_of_range("member_overrides: member " + std::to_string(member) + " of " +
                            std::to_string(d.values.size()));
  std::vector<std::string> out;
  for (std::size_t j = 0; j < d.vary.size(); ++j) {
    out.push_back(d.vary[j].key + "=" + format_exact(d.values[member][j]));
  }
  return out;
}

}  // namespace granflow::mpm
