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
#include <string>
#include <vector>

namespace granflow::calibration {

// A free parameter's prior: uniform in [lower, upper] (in log(value) with log = true). The
// update works on z = logit of the unit coordinate, so members never leave the bounds.
struct PriorBound {
  std::string key;
  double lower = 0, upper = 1;
  bool log = false;
};

struct EnsembleMethodSpec {
  long members = 64;
  int iterations = 4;        // ES-MDA assimilations, each with inflation alpha = iterations
  std::uint64_t seed = 1;    // prior sample (Latin hypercube) and data perturbations
};

// Forward model of a batch: thetas[i] (physical units) -> predictions[i] (one value per datum,
// in the order of `data`), ok[i] = false where member i could not be computed (its message in
// why[i]). Called once per iteration with all members.
struct BatchResult {
  std::vector<std::vector<double>> predictions;
  std::vector<char> ok;
  std::vector<std::string> why;
};
using BatchForward = std::function<BatchResult(const std::vector<std::vector<double>>& thetas)>;

struct EnsembleIteration {
  std::vector<std::vector<double>> thetas;  // members entering this iteration
  std::vector<double> misfit;               // per member: sum ((pred - data) / sd)^2 (NaN: failed)
  long failed = 0;
  double mean_misfit = 0, best_misfit = 0;
  double seconds = 0;                       // of the batch
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
};

// Runs ES-MDA. data and sd have one entry per datum (sd > 0). progress(iteration, result so
// far) is called after every batch (may be empty). Throws std::runtime_error when a whole
// batch fails.
EnsembleResult run_ensemble_method(const std::vector<PriorBound>& prior, const std::vector<double>& data,
                                   const std::vector<double>& sd, const BatchForward& forward,
                                   const EnsembleMethodSpec& spec,
                                   const std::function<void(int, const EnsembleResult&)>& progress = {});

}  // namespace granflow::calibration
