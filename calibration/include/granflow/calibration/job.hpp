// A calibration job (data/calibration/*.toml): the parameter set to start from, the free
// parameters with their bounds, the experiments (element tests or steady simple-shear flow
// curves, each paired with a CSV of data), the misfit and the optimisation algorithm.
// Read strictly: unknown keys, wrong types and out-of-range values are errors naming file,
// line and key (see docs/calibration.md for the format).
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <granflow/io/parameter_set.hpp>

namespace granflow::calibration {

class Experiment;

// One free parameter, addressed as "section.key" of a parameter set (frictional.phi_c_deg, ...).
struct FreeParameter {
  std::string key;
  double lower = 0, upper = 0;
  bool log = false;                    // search in log(value): for parameters spanning decades
  std::optional<double> start;         // default: the value in the starting set
  std::string experiment;              // key "test.e0@NAME": the initial void ratio of experiment NAME
};

enum class MisfitScale { Linear, Log };
enum class Normalise { Rms, Range, None };

struct MisfitSpec {
  MisfitScale scale = MisfitScale::Linear;
  Normalise normalise = Normalise::Rms;  // linear misfit only: residuals divided by the curve's RMS / range
  double failure_penalty = 1e3;          // residual assigned to every point of a curve the model cannot compute
};

struct AlgorithmSpec {
  std::string method = "nlopt";         // "nlopt": the fit below; "ensemble": ES-MDA ([ensemble], [likelihood])
  long method_line = 0;                 // its line in the job file (messages)
  std::string global = "GN_CRS2_LM";    // or "none"
  std::string local = "LN_BOBYQA";      // or "none"
  long global_evaluations = 500;
  long local_evaluations = 500;
  double max_time_s = 0;                // 0: no wall-clock limit (results then depend on the machine)
  unsigned long seed = 12345;
  long starts = 1;                      // local runs: from the global optimum, then from seeded random points
  double xtol_rel = 1e-8;
  double ftol_rel = 1e-12;
  double fd_step = 1e-4;                // relative step of the finite-difference Jacobian at the optimum
};

// The ensemble method (docs/calibration_ensemble.md).
struct EnsembleSpec {
  long members = 64;
  int iterations = 4;
  unsigned long seed = 1;
  bool polish = true;              // LN_BOBYQA from the best final member (where NLopt is built)
  long polish_evaluations = 100;
  std::string transform = "probit";  // coordinates of the update: "probit" or "logit" of the unit coordinate
};

// Gaussian likelihood of the ensemble method: the sd of each datum in the misfit's scale.
// Curve::sd (data units) where given; else log misfit: relative_sd (the sd of ln y),
// linear misfit: relative_sd x the curve's RMS.
struct LikelihoodSpec {
  double relative_sd = 0.02;
};

// A steady-shear [[experiments]] entry as read, kept so that its groups can be scored over any
// solid-fraction window (flow_curves.hpp), not only the fitted range.
struct SteadyShearSource {
  std::string name;
  std::shared_ptr<const void> selection;  // DataSelection (experiment.hpp)
  std::shared_ptr<const void> spec;       // SteadyShearSpec
  bool predict = false;
};

// [cross_validation] of a steady-shear job (docs/calibration_results.md, "Flow curves across friction").
struct CrossValidationSpec {
  bool present = false;
  std::vector<std::pair<double, double>> windows;  // solid-fraction windows [lo, hi) of the scores
  std::vector<double> bands;                       // band edges of the "which range" breakdown
  bool leave_one_group = true, leave_one_friction = true;
  // Per friction level: free keys held at their start values in the fit on that level alone
  // (constants one level cannot determine, such as V_sd(0) from mu_p = 0.5 data).
  std::vector<std::pair<double, std::vector<std::string>>> friction_held;
};

struct CalibrationJob {
  std::string file;         // the job file
  std::string name;
  io::ParameterSet start;   // parameter set the fit starts from (and whose other values it keeps)
  std::vector<FreeParameter> free;
  std::vector<std::shared_ptr<const Experiment>> experiments;
  // Held out (role = "predict"): run with the fitted set and reported, never fitted.
  std::vector<std::shared_ptr<const Experiment>> predictions;
  MisfitSpec misfit;
  AlgorithmSpec algorithm;
  EnsembleSpec ensemble;
  LikelihoodSpec likelihood;
  std::string output_name = "fitted";  // stem of the fitted parameter file
  std::vector<SteadyShearSource> steady_shear_sources;
  CrossValidationSpec cross_validation;
};

// Reads and validates a job; loads and checks every data file it names.
CalibrationJob load_job(const std::string& path);

}  // namespace granflow::calibration
