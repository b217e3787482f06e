// The fit: misfit of a parameter vector over all curves (evaluated in parallel, reduced in a
// fixed order so the result does not depend on the thread count), a global NLopt search
// followed by local refinement, and the local identifiability analysis at the optimum.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Dense>

#include <granflow/io/run_folder.hpp>

#include "ensemble_method.hpp"
#include "experiment.hpp"
#include "job.hpp"

namespace granflow::calibration {

// Persistent workers running parallel_for(n, f): f(i) for i < n, each index exactly once.
class ThreadPool {
 public:
  explicit ThreadPool(unsigned threads);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;
  void parallel_for(std::size_t n, const std::function<void(std::size_t)>& f);
  unsigned size() const { return static_cast<unsigned>(workers_.size()) + 1; }

 private:
  void work();
  std::vector<std::thread> workers_;
  std::mutex m_;
  std::condition_variable cv_, done_cv_;
  const std::function<void(std::size_t)>* job_ = nullptr;
  std::size_t n_ = 0;
  std::atomic<std::size_t> next_{0};
  std::size_t busy_ = 0;
  unsigned long generation_ = 0;
  bool stop_ = false;
};

struct CurveEvaluation {
  std::vector<double> model;  // at the data abscissae (NaN where the model failed)
  double rmse = 0;            // in data units
  double r2 = 0;              // 1 - SS_res / SS_tot in data units
  double misfit = 0;          // weighted, normalised contribution to the total misfit
  std::string failure;        // why the model failed, if it did
};

struct Evaluation {
  double misfit = 0;
  std::vector<double> residuals;      // weighted, normalised; misfit = sum of squares
  std::vector<CurveEvaluation> curves;
};

class Objective {
 public:
  // threads = 0: all cores. Throws an InputError when a log misfit meets a non-positive data value.
  Objective(const CalibrationJob& job, unsigned threads);

  std::size_t dimension() const { return job_.free.size(); }
  // Parameter values <-> unit-cube coordinates (log-scaled parameters are uniform in log).
  std::vector<double> to_unit(const std::vector<double>& theta) const;
  std::vector<double> from_unit(const std::vector<double>& u) const;
  std::vector<double> start_values() const;
  io::ParameterSet parameters_at(const std::vector<double>& theta) const;

  Evaluation evaluate(const std::vector<double>& theta) const;  // full detail
  double misfit(const std::vector<double>& theta) const { return evaluate(theta).misfit; }
  // Every experiment's prediction for many parameter vectors, [set][experiment]: batched
  // experiments get one predict_batch call with all sets (on this thread, first), the others
  // one task per set x experiment on the pool. An exception becomes ok = false.
  std::vector<std::vector<Prediction>> predict_many(const std::vector<std::vector<double>>& thetas) const;
  // The misfit, residuals, RMSE and R2 of one set's predictions ([experiment]).
  Evaluation assess(const std::vector<Prediction>& predictions) const;

  struct CurveRef {
    std::size_t experiment, curve;
  };
  const std::vector<CurveRef>& curves() const { return curves_; }
  const Curve& curve(std::size_t c) const;
  const CalibrationJob& job() const { return job_; }
  std::size_t residual_count() const { return n_residuals_; }
  unsigned threads() const { return pool_.size(); }

 private:
  const CalibrationJob& job_;
  std::vector<CurveRef> curves_;
  std::vector<double> scale_;  // per curve normalisation
  std::size_t n_residuals_ = 0;
  mutable ThreadPool pool_;
};

struct Identifiability {
  Eigen::MatrixXd sensitivity;  // curves x parameters: RMS change of the normalised curve per unit change of ln(theta)
  Eigen::MatrixXd correlation;  // parameters x parameters, from (S^T S)^-1 (NaN where undefined)
  std::vector<double> rel_sd;   // approximate relative standard deviation of each parameter (NaN: undefined)
  // Per parameter: why its rel_sd and correlations are undefined (no curve depends on it here,
  // it trades off exactly with others, no residual degree of freedom); empty when defined.
  std::vector<std::string> undefined;
  std::vector<std::pair<std::size_t, std::size_t>> correlated;  // defined and |correlation| > 0.95
  bool singular = false;
  long evaluations = 0;
  // In the search's unit cube (each range, or log range, mapped onto [0, 1]; docs/calibration.md):
  // the standard error of each parameter as a fraction of its range, sqrt(s2 (J^T J)^-1_jj) with
  // J = d r / d u (NaN: undefined), and the condition number of J^T J, the Gauss-Newton Hessian of
  // the misfit over 2 (inf: singular).
  std::vector<double> sd_range;
  double condition = 0;
  // Per parameter: "identified", "correlated" (in a pair above), "poorly identified" (sd_range above
  // kPoorlyIdentified) or "not identified" (undefined sd).
  std::vector<std::string> status;
};

// sd_range above this fraction of the range: the +-2 sd interval spans 40 % of the range searched,
// so the data pin the parameter little better than its bounds do.
inline constexpr double kPoorlyIdentified = 0.1;

// The unit-space spread of a least-squares fit from its Jacobian J = d r / d u (residuals x
// parameters) and misfit sum r^2: per parameter sqrt(s2 (J^T J)^-1_jj) with s2 = misfit / (N - n)
// (NaN where J^T J is singular in a direction that moves it, or N <= n); and cond(J^T J).
struct UnitSpread {
  std::vector<double> sd;
  double condition = 0;
};
UnitSpread gauss_newton_spread(const Eigen::MatrixXd& J, double misfit);

// What the ensemble method adds to a FitResult (algorithm.method = "ensemble").
struct EnsembleReport {
  EnsembleResult result;             // iterations, final members (physical units), summary
  std::vector<double> data, sd;      // per datum in the misfit's scale (ln y for a log misfit)
  std::vector<Evaluation> members;   // final members' curves (empty for a failed member)
  std::vector<double> best;          // best final member, before the polish
  double best_misfit = 0;            // its chi-square, sum ((g - d) / sd)^2
  double fitted_misfit = 0;          // chi-square of the written set (after the polish)
  long polish_evaluations = 0;
  std::string polish;                // what the polish did, or why it was skipped
};

// The data vector of the ensemble method, one entry per point in the order of the residuals
// (experiments in job order, their curves, the points by abscissa): ln y for a log misfit, else
// y; sd from Curve::sd (data units; divided by y for a log misfit) or the job's likelihood.
// Throws an InputError for a curve whose default sd would be 0.
void likelihood_data(const Objective& objective, std::vector<double>& data, std::vector<double>& sd);
// One set's predictions in that order and scale; false (with `why`) when any point is undefined.
bool prediction_vector(const Objective& objective, const std::vector<Prediction>& predictions,
                       std::vector<double>& out, std::string& why);

struct FitOptions {
  bool progress = true;        // progress line on stderr
  bool evaluate_only = false;  // no optimisation: report the misfit and identifiability at the start values
  // Ensemble method: the ES-MDA state is saved here after every update, and a run of the same
  // job finding it continues from it (docs/calibration.md, "Resume"). Empty: neither.
  std::string state_file;
};

struct FitResult {
  std::vector<double> start, theta;
  Evaluation at_start, at_best;
  long evaluations = 0, global_evaluations = 0, local_evaluations = 0;
  double seconds = 0;
  std::vector<int> on_bound;  // -1 lower, +1 upper, 0 inside (within 1e-6 of the range)
  Identifiability identifiability;
  io::ParameterSet fitted;
  std::string stop_reason;
  unsigned threads = 1;
  std::shared_ptr<const EnsembleReport> ensemble;  // set by the ensemble method
};

// The job's method: NLopt global + local search, or (algorithm.method = "ensemble") ES-MDA with
// the best member, polished, as the result. Without NLopt in the build only the latter runs.
FitResult fit(const Objective& objective, const FitOptions& options);
FitResult fit_ensemble(const Objective& objective, const FitOptions& options);
Identifiability identifiability(const Objective& objective, const std::vector<double>& theta, double step);

namespace detail {
// LN_BOBYQA on f over the unit cube from u (fu = f(u)) with at most max_evaluations calls; u and
// fu become the best point seen. False (nothing done, note says why) without NLopt in the build.
bool polish_bobyqa(const std::function<double(const std::vector<double>&)>& f, std::vector<double>& u, double& fu,
                   long max_evaluations, const std::vector<double>& step, double xtol_rel, std::string& note);
}  // namespace detail

// Writes fitted TOML, report.txt, report_curves.csv, report_parameters.csv, correlation.csv,
// sensitivity.csv, curves.csv and fit.png (with an ensemble also posterior.csv,
// posterior_summary.csv, posterior_correlation.csv, iterations.csv, ensemble_curves.csv,
// posterior.png and ensemble_fit.png) into the folder's staging folder, then commits it
// (manifest, swapped in). An undefined number (NaN, inf) is written as an empty cell.
void write_outputs(const Objective& objective, const FitResult& result, io::StagedFolder& folder, bool plot = true);
// The same into `dir`, locked and staged here; refuses an existing `dir` unless `force` and it
// is a granflow run folder.
void write_outputs(const Objective& objective, const FitResult& result, const std::string& dir,
                   bool force, bool plot = true);

// The text report (also printed by the command); with an ensemble, format_ensemble_report at its end.
std::string format_report(const Objective& objective, const FitResult& result);
// "python3" or "/usr/bin/python3", whichever imports matplotlib (plot scripts); "" if neither.
std::string python_with_matplotlib();
std::string format_ensemble_report(const Objective& objective, const FitResult& result);
// Per parameter: fitted value, sd as a fraction of its range, rel. s.d., status, cond(J^T J); the
// end of the command's output and of report.txt (identifiability.csv holds the same).
std::string format_identifiability(const Objective& objective, const FitResult& result);

}  // namespace granflow::calibration
