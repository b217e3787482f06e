// Ensemble design files (mpm/ensemble_design.hpp, docs/mpm_ensemble_design.md): the unit-cube
// samplers against published values and their stratification, the five methods, the overrides
// reading back bit-exactly, every refused input naming file:line and key, and the example designs
// under mpm/scenes/ensembles applied to the scenes they are written for.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <granflow/io/input_error.hpp>
#include <granflow/mpm/ensemble.hpp>
#include <granflow/mpm/ensemble_design.hpp>
#include <granflow/mpm/scene_file.hpp>

using namespace granflow;
using namespace granflow::mpm;

namespace {

const std::string kRepo = std::string(GRANFLOW_SOURCE_DIR) + "/";
constexpr double kDegree = 180 / 3.14159265358979323846;
namespace fs = std::filesystem;

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// Line numbers in the messages below refer to this text.
const std::string kLhs =
    "[design]\n"                         // 1
    "method = \"lhs\"\n"                 // 2
    "members = 4\n"                      // 3
    "[[vary]]\n"                         // 4
    "key = \"frictional.phi_c_deg\"\n"   // 5
    "range = [28.0, 34.0]\n"             // 6
    "[[vary]]\n"                         // 7
    "key = \"base.mu\"\n"                // 8
    "range = [0.2, 0.5]\n";              // 9

std::string edit(std::string s, const std::string& from, const std::string& to) {
  const auto at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return at == std::string::npos ? s : s.replace(at, from.size(), to);
}

std::string error_of(const std::string& text) {
  try {
    parse_design(text, "d.toml");
  } catch (const io::InputError& e) {
    return e.what();
  }
  return "";
}

// The design is refused with a message holding every part.
void expect_error(const std::string& text, const std::vector<std::string>& parts) {
  const std::string message = error_of(text);
  ASSERT_FALSE(message.empty()) << "accepted:\n" << text;
  for (const auto& p : parts) EXPECT_NE(message.find(p), std::string::npos) << "'" << p << "' not in: " << message;
}

std::string vary(const std::string& key, const std::string& body) {
  return "[[vary]]\nkey = \"" + key + "\"\n" + body + "\n";
}

}  // namespace

// ---- helpers and samplers

TEST(EnsembleDesign, UnitDoubleAndUniformBelowUseIntegerArithmeticOnly) {
  EXPECT_EQ(unit_double(0), 0.0);
  EXPECT_EQ(unit_double(std::uint64_t{1} << 11), 0x1.0p-53);
  EXPECT_EQ(unit_double(~std::uint64_t{0}), 1.0 - 0x1.0p-53);
  EXPECT_EQ(unit_double(std::uint64_t{1} << 63), 0.5);
  // The engine is specified bit for bit by the C++ standard (its 10000th output):
  std::mt19937_64 ref;
  ref.discard(9999);
  EXPECT_EQ(ref(), 9981545732273789042ull);
  // Pinned draws: the same on every platform.
  std::mt19937_64 rng(1);
  std::vector<std::uint64_t> draws;
  for (int i = 0; i < 8; ++i) draws.push_back(uniform_below(rng, 10));
  EXPECT_EQ(draws, (std::vector<std::uint64_t>{8, 2, 0, 6, 4, 9, 8, 5}));
  EXPECT_EQ(uniform_below(rng, 1), 0u);
  EXPECT_THROW(uniform_below(rng, 0), std::invalid_argument);
  std::vector<long> hits(3);
  for (int i = 0; i < 30000; ++i) ++hits.at(uniform_below(rng, 3));
  for (long h : hits) EXPECT_NEAR(h, 10000, 500);
}

TEST(EnsembleDesign, LatinHypercubeHasExactlyOnePointPerStratum) {
  for (long n : {1L, 2L, 3L, 7L, 64L, 1000L}) {
    const auto x = latin_hypercube(n, 3, 42);
    ASSERT_EQ(static_cast<long>(x.size()), n);
    for (int d = 0; d < 3; ++d) {
      std::vector<double> col;
      for (const auto& p : x) col.push_back(p[d]);
      std::sort(col.begin(), col.end());
      // sorted, the k-th point lies in stratum k = [fl(k/n), fl((k+1)/n)): one per stratum
      const double N = static_cast<double>(n);
      for (long k = 0; k < n; ++k) {
        EXPECT_GE(col[k], static_cast<double>(k) / N) << "n " << n << " dim " << d << " k " << k;
        EXPECT_LT(col[k], static_cast<double>(k + 1) / N) << "n " << n << " dim " << d << " k " << k;
      }
    }
  }
}

TEST(EnsembleDesign, LatinHypercubeIsReproducibleFromTheSeed) {
  EXPECT_EQ(latin_hypercube(50, 4, 7), latin_hypercube(50, 4, 7));  // bit for bit
  EXPECT_NE(latin_hypercube(50, 4, 7), latin_hypercube(50, 4, 8));
  // a variable added at the end leaves the others as they were
  const auto two = latin_hypercube(20, 2, 3), three = latin_hypercube(20, 3, 3);
  for (long i = 0; i < 20; ++i) {
    EXPECT_EQ(two[i][0], three[i][0]);
    EXPECT_EQ(two[i][1], three[i][1]);
  }
  // pinned: a platform giving other values breaks reproducibility
  const std::vector<std::vector<double>> pinned = {{0x1.e4546c04d9ff8p-2, 0x1.c17881b052b6ap-2},
                                                    {0x1.12152fc3e853fp-1, 0x1.cc4fe9f9d7bdfp-1},
                                                    {0x1.c352ba403fbbp-7, 0x1.96fbf0f2a3432p-4},
                                                    {0x1.ea901cef46875p-1, 0x1.277dde75e55b6p-1}};
  EXPECT_EQ(latin_hypercube(4, 2, 7), pinned);
  EXPECT_THROW(latin_hypercube(0, 1, 1), std::invalid_argument);
}

// Published unscrambled Sobol points (Joe-Kuo new-joe-kuo-6.21201, Gray-code order, the zero point
// skipped): 2D in SciPy's scipy/stats/tests/test_qmc.py (TestSobol.unscramble_nd); 5D in
// TensorFlow's sobol_ops_test.py (test_more_known_values). By hand: V_k = m_k / 2^k; dim 1 has
// m_k = 1 (0.5, 0.25, 0.125, ...); dim 2 (s = 1, a = 0, m_1 = 1) m_k = 2 m_(k-1) xor m_(k-1):
// 1, 3, 5, 15 -> V = 0.5, 0.75, 0.625, 0.9375; dim 3 (s = 2, a = 1, m = 1, 3) m_3 = 4 m_1 xor
// 2 m_2 xor m_1 = 4 ^ 6 ^ 1 = 3 -> V = 0.5, 0.75, 0.375. Point i is the xor of V_k over the bits
// k of gray(i) = i ^ (i >> 1): i = 4 (gray 110): dim 2 0.75 ^ 0.625 = 0.375, dim 3 0.75 ^ 0.375 =
// 0.625. Also checked, when written, against Boost.Random 1.74 sobol_engine<uint32_t, 32> for
// all 21 dimensions and 5000 points.
TEST(EnsembleDesign, SobolMatchesPublishedPoints) {
  const std::vector<std::vector<double>> published = {
      {0.5, 0.5, 0.5, 0.5, 0.5},           {0.75, 0.25, 0.25, 0.25, 0.75},      {0.25, 0.75, 0.75, 0.75, 0.25},
      {0.375, 0.375, 0.625, 0.875, 0.375}, {0.875, 0.875, 0.125, 0.375, 0.875}, {0.625, 0.125, 0.875, 0.625, 0.625},
      {0.125, 0.625, 0.375, 0.125, 0.125}, {0.1875, 0.3125, 0.9375, 0.4375, 0.5625},
      {0.6875, 0.8125, 0.4375, 0.9375, 0.0625}, {0.9375, 0.0625, 0.6875, 0.1875, 0.3125},
      {0.4375, 0.5625, 0.1875, 0.6875, 0.8125}, {0.3125, 0.1875, 0.3125, 0.5625, 0.9375},
      {0.8125, 0.6875, 0.8125, 0.0625, 0.4375}, {0.5625, 0.4375, 0.0625, 0.8125, 0.1875},
      {0.0625, 0.9375, 0.5625, 0.3125, 0.6875}, {0.09375, 0.46875, 0.46875, 0.65625, 0.28125}};
  EXPECT_EQ(sobol_points(16, 5), published);
  // skip = 0 starts at the zero point; skip moves along the sequence
  const auto from0 = sobol_points(9, 2, 0);
  EXPECT_EQ(from0[0], (std::vector<double>{0.0, 0.0}));
  EXPECT_EQ(from0[8], (std::vector<double>{0.1875, 0.3125}));
  EXPECT_EQ(sobol_points(3, 5, 4)[0], published[3]);
  // Boost.Random 1.74 sobol_engine<uint32_t, 32>, point 1000, all 21 dimensions (x 2^32)
  const std::vector<double> boost_1000 = {943718400,  415236096,  2227175424, 2906652672, 1203765248, 3896508416,
                                          197132288,  3862953984, 2151677952, 297795584,  364904448,  1094713344,
                                          692060160,  1648361472, 616562688,  1589641216, 3091202048, 1480589312,
                                          4257218560, 3116367872, 2243952640};
  const auto p = sobol_points(1, kMaxQuasiRandomDims, 1000)[0];
  for (int d = 0; d < kMaxQuasiRandomDims; ++d) EXPECT_EQ(p[d] * 0x1.0p32, boost_1000[d]) << "dim " << d + 1;
  // every coordinate is a (0, 1)-sequence: points 0..2^k-1 fill the 2^k dyadic intervals once each
  const auto all = sobol_points(1024, kMaxQuasiRandomDims, 0);
  for (int d = 0; d < kMaxQuasiRandomDims; ++d)
    for (long m : {2L, 16L, 256L, 1024L}) {
      std::vector<int> seen(m);
      for (long i = 0; i < m; ++i) ++seen[static_cast<long>(all[i][d] * m)];
      EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), m) << "dim " << d + 1 << " m " << m;
    }
  EXPECT_THROW(sobol_points(1, kMaxQuasiRandomDims + 1), std::invalid_argument);
  EXPECT_THROW(sobol_points(2, 1, (1L << 32) - 1), std::invalid_argument);
}

// Published Halton points (radical inverses, index 0 skipped): base 2 1/2, 1/4, 3/4, 1/8, 5/8,
// 3/8, 7/8; base 3 1/3, 2/3, 1/9, 4/9, 7/9, 2/9, 5/9 (SciPy scipy/stats/tests/test_qmc.py,
// TestHalton.unscramble_nd); base 5 1/5 ... 4/5, 1/25, 6/25.
TEST(EnsembleDesign, HaltonMatchesPublishedPoints) {
  const auto h = halton_points(7, 3);
  const std::vector<double> b2 = {1. / 2, 1. / 4, 3. / 4, 1. / 8, 5. / 8, 3. / 8, 7. / 8};
  const std::vector<double> b3 = {1. / 3, 2. / 3, 1. / 9, 4. / 9, 7. / 9, 2. / 9, 5. / 9};
  const std::vector<double> b5 = {1. / 5, 2. / 5, 3. / 5, 4. / 5, 1. / 25, 6. / 25, 11. / 25};
  for (int i = 0; i < 7; ++i) {
    EXPECT_EQ(h[i][0], b2[i]) << i;  // exact: one correctly rounded division
    EXPECT_EQ(h[i][1], b3[i]) << i;
    EXPECT_EQ(h[i][2], b5[i]) << i;
  }
  EXPECT_EQ(halton_points(1, 2, 0)[0], (std::vector<double>{0.0, 0.0}));
  EXPECT_EQ(halton_points(1, kMaxQuasiRandomDims)[0][kMaxQuasiRandomDims - 1], 1.0 / 73);  // 21st prime
  EXPECT_EQ(radical_inverse(11, 3), 19.0 / 27);  // 11 = 102 in base 3 -> 0.201 = 2/3 + 1/27
  EXPECT_THROW(halton_points(1, kMaxQuasiRandomDims + 1), std::invalid_argument);
}

// ---- the methods

TEST(EnsembleDesign, ListTakesTheValuesAsWritten) {
  const EnsembleDesign d = parse_design("[design]\nmethod = \"list\"\n" +
                                            vary("frictional.phi_c_deg", "values = [29.0, 31.0, 33.0]") +
                                            vary("wall[0].mu", "values = [0.1, 0.2, 0.3]"),
                                        "d.toml");
  EXPECT_EQ(d.method, "list");
  ASSERT_EQ(d.members, 3);
  EXPECT_EQ(d.values, (std::vector<std::vector<double>>{{29.0, 0.1}, {31.0, 0.2}, {33.0, 0.3}}));
  EXPECT_EQ(member_overrides(d, 1), (std::vector<std::string>{"frictional.phi_c_deg=31", "wall[0].mu=0.2"}));
  EXPECT_EQ(d.vary[1].line, 6);
}

TEST(EnsembleDesign, GridIsFullFactorialWithTheFirstVariableSlowest) {
  const EnsembleDesign d = parse_design("[design]\nmethod = \"grid\"\n" + vary("collisional.eps_n", "values = [0.5, 0.7]") +
                                            vary("base.mu", "range = [0.0, 0.4]\ncount = 3") +
                                            vary("stage[0].gate.lift_speed", "range = [0.1, 10.0]\ncount = 2\nscale = \"log\""),
                                        "d.toml");
  ASSERT_EQ(d.members, 12);
  EXPECT_EQ(d.vary[1].values, (std::vector<double>{0.0, 0.2, 0.4}));
  EXPECT_EQ(d.vary[2].values, (std::vector<double>{0.1, 10.0}));  // log grid: the ends exact
  std::vector<std::vector<double>> want;
  for (double a : {0.5, 0.7})
    for (double b : {0.0, 0.2, 0.4})
      for (double c : {0.1, 10.0}) want.push_back({a, b, c});
  EXPECT_EQ(d.values, want);
  const EnsembleDesign g = parse_design("[design]\nmethod = \"grid\"\n" + vary("initial.e0", "range = [0.5, 8.0]\ncount = 5\nscale = \"log\"") +
                                            vary("base.mu", "range = [0.3, 0.3]\ncount = 1"),
                                        "d.toml");
  ASSERT_EQ(g.members, 5);
  for (int i = 0; i < 5; ++i) {
    EXPECT_NEAR(g.values[i][0], 0.5 * std::pow(2.0, i), 1e-14) << i;  // geometric levels
    EXPECT_EQ(g.values[i][1], 0.3);
  }
}

// The levels of a grid range: count of them, the first exactly lo and the last exactly hi (linear
// and log scale, bounds that are not sums of the steps), increasing in between.
TEST(EnsembleDesign, GridLevelsReachBothEndsOfTheRange) {
  for (const char* scale : {"linear", "log"})
    for (const auto& [lo, hi] : {std::pair{0.1, 0.7}, std::pair{1e-3, 3.7}, std::pair{0.3, 0.45}})
      for (long count : {2, 3, 7, 10}) {
        char range[160];
        std::snprintf(range, sizeof range, "range = [%.17g, %.17g]\ncount = %ld\nscale = \"%s\"", lo, hi, count, scale);
        const EnsembleDesign d = parse_design("[design]\nmethod = \"grid\"\n" + vary("base.mu", range), "d.toml");
        const std::vector<double>& v = d.vary[0].values;
        ASSERT_EQ(static_cast<long>(v.size()), count) << range;
        EXPECT_EQ(v.front(), lo) << range;
        EXPECT_EQ(v.back(), hi) << range;
        for (size_t i = 1; i < v.size(); ++i) EXPECT_GE(v[i], v[i - 1]) << range << ", level " << i;
        ASSERT_EQ(d.members, count);
        EXPECT_EQ(d.values.front()[0], lo);
        EXPECT_EQ(d.values.back()[0], hi);
      }
}

TEST(EnsembleDesign, LhsMapsTheHypercubeOntoTheRangesReproducibly) {
  const EnsembleDesign d = parse_design(kLhs, "d.toml");
  EXPECT_EQ(d.seed, 1u);  // default
  ASSERT_EQ(d.members, 4);
  const auto u = latin_hypercube(4, 2, 1);
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(d.values[i][0], (1 - u[i][0]) * 28.0 + u[i][0] * 34.0);
    EXPECT_EQ(d.values[i][1], (1 - u[i][1]) * 0.2 + u[i][1] * 0.5);
  }
  EXPECT_EQ(parse_design(edit(kLhs, "members = 4\n", "members = 4\nseed = 1\n"), "d.toml").values, d.values);
  EXPECT_NE(parse_design(edit(kLhs, "members = 4\n", "members = 4\nseed = 2\n"), "d.toml").values, d.values);
  // log scale: uniform in log(value), one point per stratum of log(value), within the range
  const EnsembleDesign g = parse_design(edit(edit(kLhs, "members = 4", "members = 10"), "range = [0.2, 0.5]",
                                             "range = [1e-3, 1e1]\nscale = \"log\""),
                                        "d.toml");
  std::vector<double> k;
  for (const auto& m : g.values) k.push_back(std::log10(m[1]) + 3);  // 0..4
  std::sort(k.begin(), k.end());
  for (int i = 0; i < 10; ++i) {
    EXPECT_GE(k[i], 0.4 * i - 1e-12);
    EXPECT_LE(k[i], 0.4 * (i + 1) + 1e-12);
  }
}

TEST(EnsembleDesign, SobolAndHaltonDesignsShiftOnlyWithScramble) {
  const std::string sobol = edit(kLhs, "\"lhs\"", "\"sobol\"");
  const EnsembleDesign s = parse_design(sobol, "d.toml");
  EXPECT_EQ(s.values[0], (std::vector<double>{31.0, 0.5 * 0.2 + 0.5 * 0.5}));  // point (0.5, 0.5): the middle
  EXPECT_EQ(s.values[1][0], 0.25 * 28.0 + 0.75 * 34.0);
  const EnsembleDesign h = parse_design(edit(kLhs, "\"lhs\"", "\"halton\""), "d.toml");
  EXPECT_EQ(h.values[1][1], (1 - 2. / 3) * 0.2 + (2. / 3) * 0.5);
  const std::string scrambled = edit(sobol, "members = 4\n", "members = 4\nscramble = true\nseed = 5\n");
  const EnsembleDesign a = parse_design(scrambled, "d.toml"), b = parse_design(scrambled, "d.toml");
  EXPECT_EQ(a.values, b.values);
  EXPECT_NE(a.values, s.values);
  EXPECT_NE(parse_design(edit(scrambled, "seed = 5", "seed = 6"), "d.toml").values, a.values);
  // one shift per variable, mod 1
  const auto u = sobol_points(4, 2);
  for (int j = 0; j < 2; ++j) {
    const double lo = j ? 0.2 : 28.0, hi = j ? 0.5 : 34.0;
    auto shift = [&](int i) {
      const double t = (a.values[i][j] - lo) / (hi - lo) - u[i][j];
      return t < 0 ? t + 1 : t;
    };
    for (int i = 0; i < 4; ++i) {
      EXPECT_GE(a.values[i][j], lo);
      EXPECT_LE(a.values[i][j], hi);
      EXPECT_NEAR(shift(i), shift(0), 1e-12);
    }
  }
}

TEST(EnsembleDesign, MemberOverridesReadBackBitExactly) {
  const EnsembleDesign d = parse_design("[design]\nmethod = \"lhs\"\nmembers = 200\nseed = 11\n" +
                                            vary("numerics.p_min", "range = [1e-7, 3e-7]") +
                                            vary("frictional.phi_c_deg", "range = [-1.0, 1e6]") +
                                            vary("stage[12].duration", "range = [0.1, 0.3]"),
                                        "d.toml");
  for (long m = 0; m < d.members; ++m) {
    const auto sets = member_overrides(d, m);
    ASSERT_EQ(sets.size(), 3u);
    for (std::size_t j = 0; j < 3; ++j) {
      const std::string prefix = d.vary[j].key + "=";
      ASSERT_EQ(sets[j].compare(0, prefix.size(), prefix), 0) << sets[j];
      char* end = nullptr;
      const std::string text = sets[j].substr(prefix.size());
      EXPECT_EQ(std::strtod(text.c_str(), &end), d.values[m][j]) << sets[j];
      EXPECT_EQ(*end, '\0') << sets[j];
    }
  }
  EXPECT_THROW(member_overrides(d, -1), std::out_of_range);
  EXPECT_THROW(member_overrides(d, d.members), std::out_of_range);
}

// ---- refused designs: each names file:line and the key

TEST(EnsembleDesign, RefusesUnknownKeys) {
  expect_error(edit(kLhs, "members = 4\n", "members = 4\nsed = 3\n"), {"d.toml:4", "unknown key 'design.sed'"});
  expect_error(edit(kLhs, "range = [28.0, 34.0]\n", "range = [28.0, 34.0]\nunit = \"deg\"\n"),
               {"d.toml:7", "unknown key 'vary[0].unit'"});
  expect_error(kLhs + "[scene]\nfile = \"x\"\n", {"d.toml:10", "unknown key 'scene'"});
  expect_error(edit(kLhs, "\"lhs\"", "\"random\""), {"d.toml:2", "'design.method'", "must be one of"});
}

TEST(EnsembleDesign, RefusesAMissingDesignOrVary) {
  expect_error("[design]\nmethod = \"lhs\"\nmembers = 4\n", {"d.toml", "'vary'", "at least one [[vary]]"});
  expect_error(vary("base.mu", "range = [0.1, 0.2]"), {"d.toml", "[design]", "missing"});
  expect_error(edit(kLhs, "method = \"lhs\"\n", ""), {"d.toml", "'design.method'", "required"});
  expect_error(edit(kLhs, "key = \"base.mu\"\n", ""), {"d.toml:7", "'vary[1].key'", "required"});
  expect_error(edit(kLhs, "range = [0.2", "ranges = [0.2"), {"d.toml:7", "'vary[1].range'", "required", "'vary[1].ranges'; a typo?"});
}

TEST(EnsembleDesign, RefusesADuplicateKeyNamingBothLines) {
  expect_error(edit(kLhs, "\"base.mu\"", "\"frictional.phi_c_deg\""),
               {"d.toml:8", "'vary[1].key'", "varied twice", "at line 4"});
  expect_error(edit(edit(kLhs, "\"base.mu\"", "\"wall[00].mu\""), "\"frictional.phi_c_deg\"", "\"wall[0].mu\""),
               {"d.toml:8", "varied twice"});
}

TEST(EnsembleDesign, RefusesAnEmptyRange) {
  expect_error(edit(kLhs, "[28.0, 34.0]", "[34.0, 28.0]"), {"d.toml:6", "'vary[0].range'", "empty range"});
  expect_error(edit(edit(kLhs, "\"lhs\"", "\"sobol\""), "[28.0, 34.0]", "[30, 30]"), {"d.toml:6", "empty range"});
  expect_error(edit(kLhs, "[28.0, 34.0]", "[28.0]"), {"d.toml:6", "needs two numbers"});
  expect_error("[design]\nmethod = \"grid\"\n" + vary("base.mu", "range = [0.3, 0.3]\ncount = 3"),
               {"d.toml:5", "'vary[0].range'", "empty range"});
  expect_error("[design]\nmethod = \"grid\"\n" + vary("base.mu", "range = [0.3, 0.4]\ncount = 1"),
               {"d.toml:6", "'vary[0].count'", "needs lo == hi"});
}

TEST(EnsembleDesign, RefusesMembersOutOfRangeOrWhereDerived) {
  expect_error(edit(kLhs, "members = 4", "members = 0"), {"d.toml:3", "'design.members'", "must be in [1, 100000], got 0"});
  expect_error(edit(kLhs, "members = 4", "members = 100001"), {"d.toml:3", "'design.members'", "got 100001"});
  expect_error(edit(kLhs, "members = 4\n", ""), {"d.toml", "'design.members'", "required"});
  expect_error("[design]\nmethod = \"list\"\nmembers = 2\n" + vary("base.mu", "values = [0.1, 0.2]"),
               {"d.toml:3", "'design.members'", "not allowed with method = \"list\""});
  expect_error("[design]\nmethod = \"grid\"\nmembers = 2\n" + vary("base.mu", "values = [0.1, 0.2]"),
               {"d.toml:3", "'design.members'", "not allowed with method = \"grid\""});
  std::string big = "[design]\nmethod = \"grid\"\n";
  for (const char* k : {"a.x", "a.y", "a.z"}) big += vary(k, "range = [0, 1]\ncount = 100");
  expect_error(big, {"d.toml:14", "'vary[2].count'", "more than 100000 members"});
}

TEST(EnsembleDesign, RefusesListsOfDifferentLengthsNamingBothKeys) {
  expect_error("[design]\nmethod = \"list\"\n" + vary("frictional.phi_c_deg", "values = [29, 31, 33]") +
                   vary("base.mu", "values = [0.1, 0.2]"),
               {"d.toml:8", "'vary[1].values'", "'base.mu' has 2 values", "'frictional.phi_c_deg' (line 3) has 3"});
}

TEST(EnsembleDesign, RefusesAGridCountBelowOne) {
  expect_error("[design]\nmethod = \"grid\"\n" + vary("base.mu", "range = [0.1, 0.4]\ncount = 0"),
               {"d.toml:6", "'vary[0].count'", "must be in [1, 100000], got 0"});
  expect_error("[design]\nmethod = \"grid\"\n" + vary("base.mu", "range = [0.1, 0.4]"), {"'vary[0].count'", "required"});
  expect_error("[design]\nmethod = \"grid\"\n" + vary("base.mu", ""), {"d.toml:3", "values (the levels) or range and count"});
}

TEST(EnsembleDesign, RefusesTooManyVariablesForSobolAndHalton) {
  for (const char* method : {"sobol", "halton"}) {
    std::string text = std::string("[design]\nmethod = \"") + method + "\"\nmembers = 8\n";
    for (int i = 0; i <= kMaxQuasiRandomDims; ++i) text += vary("p.k" + std::to_string(i), "range = [0, 1]");
    expect_error(text, {"d.toml:" + std::to_string(5 + 3 * kMaxQuasiRandomDims), "'vary[21].key'", "at most 21 variables"});
  }
  std::string lhs = "[design]\nmethod = \"lhs\"\nmembers = 8\n";  // no limit for lhs
  for (int i = 0; i < 30; ++i) lhs += vary("p.k" + std::to_string(i), "range = [0, 1]");
  EXPECT_EQ(parse_design(lhs, "d.toml").vary.size(), 30u);
}

TEST(EnsembleDesign, RefusesLogScaleOverARangeNotAboveZero) {
  expect_error(edit(kLhs, "range = [0.2, 0.5]", "range = [0.0, 0.5]\nscale = \"log\""),
               {"d.toml:9", "'vary[1].range'", "scale = \"log\" needs a range above 0"});
  expect_error(edit(kLhs, "range = [0.2, 0.5]", "range = [0.2, 0.5]\nscale = \"ln\""), {"'vary[1].scale'", "must be one of"});
}

TEST(EnsembleDesign, RefusesKeysThatAreNotSetKeys) {
  for (const char* bad : {"phi c", "", "frictional..phi_c_deg", ".mu", "base.", "stage[x].duration", "stage[1]",
                          "stage[].duration", "stage[1234567].duration", "frictional.phi_c_deg=30", "wall[0]mu", "a/b"})
    expect_error(edit(kLhs, "\"base.mu\"", std::string("\"") + bad + "\""),
                 {"d.toml:8", "'vary[1].key'", "is not a --set key"});
  for (const char* bad : {":frictional.phi_c_deg", "we ak:frictional.phi_c_deg", "weak:", "a:b:c.d"})
    expect_error(edit(kLhs, "\"base.mu\"", std::string("\"") + bad + "\""),
                 {"d.toml:8", "'vary[1].key'", "is not a --set key"});
  for (const char* good : {"wall[0].mu", "stage[0].gate.lift_speed", "collisional.eps_n", "initial.e0", "grid.h", "x-y.z_2",
                           "weak:frictional.phi_c_deg", "weak:e0"})
    EXPECT_NO_THROW(parse_design(edit(kLhs, "\"base.mu\"", std::string("\"") + good + "\""), "d.toml")) << good;
}

TEST(EnsembleDesign, RefusesSeedScrambleValuesAndRangeWhereTheyAreNotUsed) {
  expect_error(edit(edit(kLhs, "\"lhs\"", "\"sobol\""), "members = 4\n", "members = 4\nseed = 3\n"),
               {"d.toml:4", "'design.seed'", "needs scramble = true"});
  expect_error(edit(kLhs, "members = 4\n", "members = 4\nscramble = true\n"), {"d.toml:4", "'design.scramble'"});
  expect_error("[design]\nmethod = \"list\"\nseed = 2\n" + vary("base.mu", "values = [0.1]"), {"d.toml:3", "'design.seed'"});
  expect_error(edit(kLhs, "range = [0.2, 0.5]", "values = [0.2, 0.5]"), {"d.toml:9", "'vary[1].values'", "range = [lo, hi]"});
  expect_error("[design]\nmethod = \"list\"\n" + vary("base.mu", "values = [0.1]\nrange = [0, 1]"),
               {"d.toml:6", "'vary[0].range'", "not used with method = \"list\""});
  expect_error("[design]\nmethod = \"grid\"\n" + vary("base.mu", "values = [0.1]\ncount = 2"),
               {"d.toml:6", "'vary[0].count'", "either values"});
  expect_error(edit(kLhs, "members = 4", "members = 4.0"), {"d.toml:3", "expected an integer"});
  expect_error(edit(kLhs, "members = 4", "members = 4\nseed = -1"), {"d.toml:4", "'design.seed'"});
}

TEST(EnsembleDesign, SyntaxErrorsAndMissingFilesNameTheFile) {
  expect_error(edit(kLhs, "members = 4", "members = = 4"), {"d.toml:3", "TOML syntax error"});
  try {
    load_design("/nonexistent/design.toml");
    FAIL() << "accepted a missing file";
  } catch (const io::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/design.toml"), std::string::npos) << e.what();
  }
}

// NAME:KEY varies one material of a scene of several; the other keeps its values.
TEST(EnsembleDesign, MaterialKeysVaryOneMaterial) {
  const EnsembleDesign d = parse_design("[design]\nmethod = \"list\"\n" +
                                            vary("weak:frictional.phi_c_deg", "values = [18.0, 22.0]") +
                                            vary("weak:e0", "values = [0.9, 0.92]"),
                                        "d.toml");
  std::string scene = slurp(kRepo + "mpm/scenes/column_collapse_ci.toml");
  scene = edit(edit(scene, "[material]\n", "[[material]]\nname = \"strong\"\n"),
               "[[body]]\nmin = [0.0, 0.0]\nmax = [0.20, 0.10]\n",
               "[[material]]\nname = \"weak\"\nparameters = \"column_collapse\"\nmodel = \"phase_transition\"\n"
               "[[body]]\nmin = [0.0, 0.0]\nmax = [0.20, 0.04]\nmaterial = \"weak\"\n"
               "[[body]]\nmin = [0.0, 0.04]\nmax = [0.20, 0.10]\nmaterial = \"strong\"\n");
  const std::string path = (fs::temp_directory_path() / ("granflow_design_two_" + std::to_string(std::rand()) + ".toml")).string();
  std::ofstream(path) << scene;
  std::vector<SceneSetup> ms;
  for (long m = 0; m < d.members; ++m) {
    SceneOverrides o;
    o.sets = member_overrides(d, m);
    const Scene sc = load_scene(path, o);
    ASSERT_EQ(sc.material_count(), 2);
    EXPECT_NEAR(sc.material_at(1).params.f.phi_c * kDegree, d.values[m][0], 1e-12);
    EXPECT_EQ(sc.material_at(1).e0, d.values[m][1]);
    EXPECT_EQ(sc.material_at(0).e0, 0.95);  // the file's, for both members
    EXPECT_NEAR(sc.material_at(0).params.f.phi_c * kDegree, 19.8, 1e-12);
    ms.push_back(make_setup_for_file(sc));
  }
  const SceneSetup su = make_ensemble_setup(ms);
  EXPECT_EQ(su.member_materials.size(), 4u);  // member after member, two materials each
  EXPECT_EQ(su.point_material.size(), static_cast<size_t>(su.particles.n));
  fs::remove(path);
}

// ---- the shipped examples, applied to the scenes they are written for

TEST(EnsembleDesign, ExampleDesignsApplyToTheirScenes) {
  const EnsembleDesign col = load_design(kRepo + "mpm/scenes/ensembles/column_phi_lhs.toml");
  EXPECT_EQ(col.method, "lhs");
  ASSERT_EQ(col.members, 8);
  for (const char* scene : {"column_collapse.toml", "column_collapse_frictional.toml", "column_collapse_ci.toml"})
    for (long m = 0; m < col.members; ++m) {
      SceneOverrides o;
      o.sets = member_overrides(col, m);
      const Scene sc = load_scene(kRepo + "mpm/scenes/" + scene, o);
      EXPECT_NEAR(sc.material.params.f.phi_c * kDegree, col.values[m][0], 1e-12) << scene;
      EXPECT_EQ(sc.material.e0, col.values[m][1]) << scene;
      if (std::string(scene) == "column_collapse_ci.toml") make_setup_for_file(sc);
    }
  // why material.e0: the column scenes give it, and it wins over the parameter set's initial.e0,
  // so varying that is refused, naming both (issue 50: the members ran identical)
  try {
    load_scene(kRepo + "mpm/scenes/column_collapse.toml", {"", {"initial.e0=0.9"}});
    ADD_FAILURE() << "a --set initial.e0 under material.e0 was accepted";
  } catch (const io::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--set 'initial.e0=0.9' changes nothing"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("column_collapse.toml:25: 'material.e0' takes precedence"), std::string::npos)
        << e.what();
  }

  const EnsembleDesign fl = load_design(kRepo + "mpm/scenes/ensembles/flume_study.toml");
  EXPECT_EQ(fl.method, "sobol");
  ASSERT_EQ(fl.members, 64);
  EXPECT_EQ(fl.vary[3].key, "stage[1].gate.lift_speed");
  EXPECT_TRUE(fl.vary[3].log_scale);
  // the shipped flume has no gate in its flow stage: the design's comment gives these two
  const std::vector<std::string> gate = {"stage[1].gate.point=[0.35355, 1.27279]", "stage[1].gate.normal=[1.0, 0.0]"};
  for (const char* scene : {"flume.toml", "flume_frictional.toml", "flume_ci.toml"})
    for (long m = 0; m < fl.members; ++m) {
      SceneOverrides o;
      o.sets = gate;
      for (const auto& s : member_overrides(fl, m)) o.sets.push_back(s);
      const Scene sc = load_scene(kRepo + "mpm/scenes/" + scene, o);
      EXPECT_NEAR(sc.material.params.f.phi_c * kDegree, fl.values[m][0], 1e-12) << scene;
      EXPECT_EQ(sc.material.e0, fl.values[m][1]) << scene;
      ASSERT_TRUE(sc.base && sc.base->mu);
      EXPECT_EQ(*sc.base->mu, fl.values[m][2]) << scene;
      ASSERT_TRUE(sc.stages.at(1).gate);
      EXPECT_EQ(sc.stages[1].gate->lift_speed, fl.values[m][3]) << scene;
      EXPECT_GE(fl.values[m][3], 0.5);
      EXPECT_LE(fl.values[m][3], 2.0);
      if (std::string(scene) == "flume_ci.toml") make_setup_for_file(sc);
    }
  // without the gate in stage[1] the lift speed has nowhere to go
  SceneOverrides bare;
  bare.sets = member_overrides(fl, 0);
  EXPECT_THROW(load_scene(kRepo + "mpm/scenes/flume.toml", bare), io::InputError);
}
