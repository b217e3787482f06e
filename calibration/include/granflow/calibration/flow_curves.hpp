// Steady-shear flow curves across groups (issue 25; docs/calibration_results.md, "Flow
// curves across friction"): each group (one friction and restitution of the data) scored over solid-fraction
// windows by the log-RMSE of p, s and T, the error of s/p against the inertial number, and the
// cross-validation tables: leave one group out, and leave one friction level out.
#pragma once

#include <string>
#include <vector>

#include "job.hpp"

namespace granflow::calibration {

// One group scored with one parameter set. rmse[w]: RMS of ln(model/data) over p, s and T at the
// points of window w (NaN: no point); band_rmse[b] the same over the band [bands[b], bands[b+1]).
struct GroupScore {
  std::string name;
  double mu_p = 0, eps_n = 0;
  std::vector<double> rmse, band_rmse;
  std::vector<int> points;   // per window: data points scored (each gives three ratios)
  int undefined = 0;         // points of the windows where the model has no value (V_s >= V_sd)
  double friction_rmse = 0;  // RMS of ln(mu_model/mu_data), mu = s/p, first window
};

// Every point of a group: data and model (the fitted set) for the plots and the mu(I) table.
struct FlowPoint {
  std::string group;
  double nu, p, s, T, p_m, s_m, T_m;  // model NaN where undefined
};

struct CrossValidationRow {
  std::string left_out;              // group name, or "mu_p = 0.5" for a friction level
  std::vector<GroupScore> scores;    // the groups left out, scored by the fit without them
  double fit_seconds = 0;
  std::vector<double> theta;         // the fitted free parameters
};

struct FlowCurveReport {
  std::vector<std::pair<double, double>> windows;
  std::vector<double> bands;
  std::vector<std::string> free_keys;
  std::vector<GroupScore> fitted;    // every group with the set fitted to all groups
  std::vector<double> overall;       // per window: RMS over every point of every group
  std::vector<FlowPoint> points;
  // s/p against I = 1/sqrt(p) (DEM units): RMS of ln(mu_model/mu_data) per I band, first window
  std::vector<double> I_edges;
  std::vector<double> I_band_rmse;
  std::vector<int> I_band_points;
  std::vector<CrossValidationRow> leave_one_group, leave_one_friction;
  double cv_seconds = 0;
};

// Scores the job's steady-shear groups with `set` (every point of the data, not only the fitted range).
std::vector<GroupScore> score_groups(const CalibrationJob& job, const io::ParameterSet& set,
                                     std::vector<FlowPoint>* points = nullptr);

// The report of the fit `fitted` and, as the job's [cross_validation] asks, the cross-validation
// fits (each from the job's start, with its algorithm) on `threads` threads.
FlowCurveReport flow_curve_report(const CalibrationJob& job, const io::ParameterSet& fitted, unsigned threads,
                                  bool progress);

std::string format_flow_curve_report(const FlowCurveReport& r);
// flow_scores.csv, flow_cv_groups.csv, flow_cv_friction.csv, flow_points.csv, flow_report.txt and
// (plot) flow_<group>.png per group and flow_mu_I.png by scripts/plot_flow_curves.py.
void write_flow_curve_report(const FlowCurveReport& r, const std::string& dir, bool plot);

// Worst group of a list in window w (the largest rmse[w]); -1 if none is defined.
int worst_group(const std::vector<GroupScore>& scores, std::size_t w);

}  // namespace granflow::calibration
