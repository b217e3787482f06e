// Design files of MPM ensembles (docs/mpm_ensemble_design.md): which --set keys vary and how
// (list, full-factorial grid, Latin hypercube, Sobol, Halton), read strictly (errors name
// file:line and key) and sampled into one list of KEY=VALUE overrides per member.
// Whether a key exists in the scene or parameter set is checked when the overrides are applied.
#pragma once

#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace granflow::mpm {

inline constexpr long kMaxDesignMembers = 100000;
// Variables of one Sobol or Halton design (Joe-Kuo direction numbers / primes held here).
inline constexpr int kMaxQuasiRandomDims = 21;

struct DesignVariable {
  std::string key;  // a --set key: frictional.phi_c_deg, base.mu, stage[1].gate.lift_speed
  long line = 0;    // line of the [[vary]] entry
  // list: the members' values; grid: the levels (given, or count points over the range)
  std::vector<double> values;
  double lo = 0, hi = 0;  // range (lhs, sobol, halton; grid with count)
  long count = 0;         // grid levels from the range; 0 when values are given
  bool log_scale = false;
};

struct EnsembleDesign {
  std::string file;
  std::string method;  // as written: list, grid, lhs, sobol, halton
  long members = 0;
  std::uint64_t seed = 1;
  bool scramble = false;
  std::vector<DesignVariable> vary;
  std::vector<std::vector<double>> values;  // values[member][variable], filled by load
};

// Reads, validates and samples a design file; io::InputError naming file:line and key.
EnsembleDesign load_design(const std::string& path);
// The same from TOML text; `name` stands for the file in messages.
EnsembleDesign parse_design(const std::string& toml_text, const std::string& name);
// A double in the fewest significant digits (15 to 17) that read back to it exactly.
std::string format_exact(double v);
// "key=value" for every variable, the value printed with format_exact (reads back bit-exactly).
std::vector<std::string> member_overrides(const EnsembleDesign& d, long member);

// Unit-cube samplers: n points of dims coordinates, points[i][d] in [0, 1).
// Latin hypercube: per dimension in turn, a Fisher-Yates permutation of the n strata, then one
// jitter per point, from std::mt19937_64(seed); point i lies in [fl(s/n), fl((s+1)/n)) of its
// stratum s. Integer arithmetic and IEEE operations only: the same on every platform.
std::vector<std::vector<double>> latin_hypercube(long n, int dims, std::uint64_t seed);
// Sobol points (Gray-code order, Joe-Kuo new-joe-kuo-6.21201, 32 bits) of indices skip..skip+n-1;
// index 0 is the all-zero point.
std::vector<std::vector<double>> sobol_points(long n, int dims, long skip = 1);
// Halton points: radical inverses of indices skip..skip+n-1 in the primes 2, 3, 5, ...
std::vector<std::vector<double>> halton_points(long n, int dims, long skip = 1);

// The helpers the samplers draw with (exposed for tests).
// The top 53 bits as a double in [0, 1): (bits >> 11) * 2^-53.
double unit_double(std::uint64_t bits);
// Uniform integer in [0, bound) (bound >= 1) without modulo bias, by rejection.
std::uint64_t uniform_below(std::mt19937_64& rng, std::uint64_t bound);
// Radical inverse of i in base b, as the division of two exact integers (correctly rounded).
double radical_inverse(std::uint64_t i, unsigned base);

}  // namespace granflow::mpm
