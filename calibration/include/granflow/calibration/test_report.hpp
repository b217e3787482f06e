// Per-test report of a calibration on measured element tests (issue 24): every fitted and
// held-out experiment run with the fitted set, and its errors in the terms of soil testing.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include <granflow/io/parameter_set.hpp>

#include "job.hpp"

namespace granflow::calibration {

// One test. Curves are recognised by their model output: q ("q", "q_axial"), p' ("p", "p_f"),
// void ratio ("e") and volumetric strain ("eps_v"). NaN: not applicable or not computable.
struct TestMetrics {
  std::string test, role, path;  // role: "fit" or "predict"; path: the element-test loading path
  double e0 = std::numeric_limits<double>::quiet_NaN();         // initial void ratio used (fitted for a per-test e0)
  bool e0_fitted = false;
  double peak_q = std::numeric_limits<double>::quiet_NaN();     // max |q| of the data [Pa]
  double rms_q = std::numeric_limits<double>::quiet_NaN();      // RMS(model - data) of q / peak_q
  double rms_p = std::numeric_limits<double>::quiet_NaN();      // RMS(model - data) of p' / peak_q
  double e_rms = std::numeric_limits<double>::quiet_NaN(), e_max = std::numeric_limits<double>::quiet_NaN();
  double eps_v_rms = std::numeric_limits<double>::quiet_NaN(), eps_v_max = std::numeric_limits<double>::quiet_NaN();
  double min_p_data = std::numeric_limits<double>::quiet_NaN();   // min p'/p'0 (undrained tests)
  double min_p_model = std::numeric_limits<double>::quiet_NaN();
  std::string failure;  // why the model could not be run or evaluated everywhere
};

// Model values of one curve of one test (long format for plots).
struct TestCurve {
  std::string test, role, data_column, model_output, abscissa;
  std::vector<double> x, data, model;
};

struct TestReport {
  std::vector<TestMetrics> tests;
  std::vector<TestCurve> curves;
};

// Runs every experiment of the job (fitted and held out) with `fitted` (which carries any
// per-test e0) and computes the metrics.
TestReport evaluate_tests(const CalibrationJob& job, const io::ParameterSet& fitted);

// The table as text (also printed by the command), with the goals checked.
std::string format_test_report(const TestReport& report);

// Writes tests.csv, test_curves.csv, tests.txt and (plot = true, python3 with matplotlib)
// tests_q_p.png, tests_q_eps1.png, tests_epsv_eps1.png, tests_e_logp.png into `dir`.
void write_test_report(const TestReport& report, const io::ParameterSet& fitted, const std::string& dir, bool plot);

}  // namespace granflow::calibration
