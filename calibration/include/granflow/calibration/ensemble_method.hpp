// The iterative ensemble method of calibration: the ensemble smoother with multiple data
// assimilation (ES-MDA; Emerick & Reynolds 2013, Computers & Geosciences 55:3-15). Each iteration
// evaluates the whole ensemble in one batch (an MPM ensemble run, or threads over element and
// flow-curve experiments) and moves every member by the Kalman-type update with the data
// perturbed by the inflated noise. For a linear model with Gaussian prior and noise the final
// ensemble samples the posterior; in general it approximates it. No NLopt or SUNDIALS: it builds
// where the GPU is.
#pragma once

#include <cstdint>
#include <functional>
#include <random>
#include <string>
#include <vector>

namespace granflow::calibration {

// A free parameter's prior: uniform in [lower, upper] (in log(value) with log = true). The
// update works on z = probit (or logit) of the unit coordinate u, so members never leave the bounds.
struct PriorBound {
  std::string key;
  double lower = 0, upper = 1;
  bool log = false;
};

// z of the unit coordinate u. Probit (z = Phi^-1(u)): z of the uniform prior is exactly standard
// normal, the Gaussian prior the update assumes. Logit (z = ln(u / (1 - u))): logistic z, whose
// heavy tails leave prior members far out in flat regions of the model for more iterations.
enum class UnitTransform { Probit, Logit };


// Forward model of a batch: thetas[i] (physical units) -> predictions[i] (one value per datum,
// in the order of `data`), ok[i] = false where member i could not be computed (its message in
// why[i]). Called once per batch (iterations + 1 times) with all members.
struct BatchResult {
  std::vector<std::vector<double>> predictions;
  std::vector<char> ok;
  std::vector<std::string> why;
};
using BatchForward = std::function<BatchResult(const std::vector<std::vector<double>>& thetas)>;

struct EnsembleIteration {
  std::vector<std::vector<double>> thetas;  // members entering this iteration
  std::vector<std::string> why;             // per member: why it failed (empty: ok)
  std::vector<double> misfit;               // per member: sum ((pred - data) / sd)^2 (NaN: failed)
  long failed = 0;
  double mean_misfit = 0, best_misfit = 0;
  double seconds = 0;                       // of the batch
};

// Where the iterations stand after an update: what a resumed run starts from.
struct EsmdaState {
  int next = 1;                             // the iteration whose batch comes next (1..iterations)
  std::vector<std::vector<double>> z;       // members entering it (unbounded coordinates)
  std::vector<EnsembleIteration> done;      // the iterations before it (`next` entries)
  long replaced = 0;
  double seconds = 0;                       // of the iterations before it
};

struct EnsembleMethodSpec {
  long members = 64;
  int iterations = 4;        // ES-MDA assimilations, each with inflation alpha = iterations
  std::uint64_t seed = 1;    // prior sample (Latin hypercube) and data perturbations
  double truncation = 0.999; // energy (sum of squared singular values) kept of the scaled prediction anomalies
  UnitTransform transform = UnitTransform::Probit;
  // Continue from a saved state (granflow calibrate's resume), and save one after every update.
  // The random streams are seeded per iteration, so a resumed run equals an uninterrupted one.
  const EsmdaState* resume = nullptr;
  std::function<void(const EsmdaState&)> save;
};

struct ParameterSummary {
  double mean = 0, median = 0, q05 = 0, q95 = 0, sd = 0;
};

struct EnsembleResult {
  std::vector<EnsembleIteration> iterations;  // iterations + 1 entries: the last is the posterior's evaluation
  std::vector<std::vector<double>> posterior; // final members (physical units)
  std::vector<std::vector<double>> predictions;  // of the final members
  std::vector<char> ok;
  std::vector<ParameterSummary> summary;      // per free parameter, over the ok final members
  std::vector<std::vector<double>> correlation;  // free x free, over the ok final members
  long best = -1;                             // final member with the least misfit
  double seconds = 0;
  long replaced = 0;                          // failed members replaced by copies of ok ones, all updates
};

// Runs ES-MDA. data and sd have one entry per datum (sd > 0). progress(iteration, result so
// far) is called after every batch (may be empty). Throws std::runtime_error when a whole
// batch fails (fewer than two members computed before an update, none at the end).
//
// Prior: a Latin hypercube of spec.members points in the unit cube (own generator: the same
// sample with every standard library), u -> z = probit(u) or logit(u). Each update uses the ensemble
// covariances of the members computed in that batch; a member that failed is first replaced by
// a copy of a randomly drawn computed one (z and predictions), and moves on with its own data
// perturbation. The gain is applied through the truncated SVD of the prediction anomalies
// scaled by sd, so no m x m matrix is formed (m data, N members: O(m N^2)).
EnsembleResult run_ensemble_method(const std::vector<PriorBound>& prior, const std::vector<double>& data,
                                   const std::vector<double>& sd, const BatchForward& forward,
                                   const EnsembleMethodSpec& spec,
                                   const std::function<void(int, const EnsembleResult&)>& progress = {});

// The same iterations on unbounded coordinates from a given prior ensemble (z0[i]: member i;
// spec.members is ignored): forward receives z, the result holds z. run_ensemble_method is
// this with the Latin hypercube and the unit transform; exposed for the linear-Gaussian check.
EnsembleResult run_esmda(const std::vector<std::vector<double>>& z0, const std::vector<double>& data,
                         const std::vector<double>& sd, const BatchForward& forward, const EnsembleMethodSpec& spec,
                         const std::function<void(int, const EnsembleResult&)>& progress = {});

// Latin hypercube of `members` points in (0, 1)^dims from std::mt19937_64(seed), integer
// arithmetic for the strata (points[i][j]).
std::vector<std::vector<double>> latin_hypercube_unit(long members, std::size_t dims, std::uint64_t seed);

// Standard normal deviates by Box-Muller from std::mt19937_64 (53-bit uniforms): the same
// sequence with every standard library.
class NormalStream {
 public:
  explicit NormalStream(std::uint64_t seed) : rng_(seed) {}
  double operator()();
  double uniform();  // in (0, 1)

 private:
  std::mt19937_64 rng_;
  double spare_ = 0;
  bool has_spare_ = false;
};

// Per-parameter summary (mean, median, 5/95 % quantiles by linear interpolation, sample s.d.)
// and Pearson correlation of the rows of `members` where ok[i] (all when ok is empty).
void summarise_members(const std::vector<std::vector<double>>& members, const std::vector<char>& ok,
                       std::vector<ParameterSummary>& summary, std::vector<std::vector<double>>& correlation);

}  // namespace granflow::calibration
