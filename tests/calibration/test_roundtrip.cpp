// Round trips through the element-test driver: curves generated from a known parameter set,
// 2 % Gaussian noise (fixed seed), a start 30 % away, and the identifiable parameters recovered
// within 5 %. Which parameters are identifiable from which tests is decided by the Jacobian
// analysis at the optimum and stated in docs/calibration_results.md.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iostream>
#include <sstream>

#include <granflow/calibration/fit.hpp>
#include <granflow/calibration/job.hpp>
#include <granflow/calibration/synthesize.hpp>

#include "helpers.hpp"
#include <granflow/io/parameter_set.hpp>

namespace granflow::calibration::test {

namespace {

std::string read(const std::string& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

FitResult run_fit(const CalibrationJob& job, unsigned threads = 0) {
  Objective obj(job, threads);
  FitOptions fo;
  fo.progress = false;
  return fit(obj, fo);
}

double value(const CalibrationJob& job, const FitResult& r, const std::string& key) {
  for (std::size_t j = 0; j < job.free.size(); ++j)
    if (job.free[j].key == key) return r.theta[j];
  ADD_FAILURE() << key;
  return 0;
}

}  // namespace

// Table 1 frictional set: undrained simple shear (tau, sigma_n vs gamma) and drained triaxial
// (q, eps_v vs eps_a), e0 = 0.85 from 100 kPa. The shipped job is used with freshly synthesised
// data (another noise seed than the committed example data).
TEST(CalibrationRoundTrip, FrictionalFourParametersFromShearAndTriaxial) {
  Scratch dir;
  const std::string src = source_dir() + "/data/calibration/";
  dir.write("synthetic/frictional_start.toml", read(src + "synthetic/frictional_start.toml"));
  const std::string job_path = dir.write("frictional_synthetic.toml", read(src + "frictional_synthetic.toml"));
  SynthesisOptions s;
  s.truth = io::load_parameter_set("frictional_element");
  s.noise = 0.02;
  s.seed = 2024;
  synthesize_job_data(job_path, s);
  const CalibrationJob job = load_job(job_path);
  Objective obj(job, 0);
  FitOptions fo;
  fo.progress = false;
  const FitResult r = fit(obj, fo);
  const auto& f = *s.truth.frictional;
  expect_recovered(job, r,
                   {{"frictional.phi_c_deg", 30.0}, {"frictional.A_d", f.A_d}, {"frictional.k_p", f.k_p},
                    {"frictional.n_p", f.n_p}},
                   {"frictional.phi_c_deg"}, format_report(obj, r));
  // With this seed the fit also recovers the three parameters the analysis finds strongly
  // correlated (A_d, k_p, n_p trade off along one valley): check them as well.
  EXPECT_NEAR(value(job, r, "frictional.A_d"), f.A_d, 0.05 * f.A_d);
  EXPECT_NEAR(value(job, r, "frictional.k_p"), f.k_p, 0.05 * f.k_p);
  EXPECT_NEAR(value(job, r, "frictional.n_p"), f.n_p, 0.05 * f.n_p);
  std::cout << format_report(obj, r);
}

namespace {

// Table 3 element-test set, collisional part: undrained simple shear at constant acceleration
// 50 s^-2 (Fig. 5 protocol) for e0 = 0.99 and 1.05; tau and sigma_n against time. Writes the
// start set and the job (with `method` as its algorithm tables) and synthesises the data.
std::string collisional_job(const Scratch& dir, const std::string& method) {
  dir.write("start.toml", R"(name = "Table 3 element set, e_sd -30 %, eps_n -30 %, V_m -30 %"
[collisional]
rho_p = 1050
d = 1.0e-3
e_sd = 0.644
V_m = 0.28
eps_n = 0.49
mu_p = 0.1
)");
  std::string exp;
  for (const char* e0 : {"0.99", "1.05"}) {
    exp += std::string("[[experiments]]\nname = \"shear_e") + e0 +
           "\"\nkind = \"element\"\ndata = \"shear_" + e0 +
           ".csv\"\nabscissa = \"time\"\nquantity = \"time\"\ntargets = { tau = \"tau\", sigma_n = \"sigma_n\" }\n"
           "[experiments.test]\npath = \"undrained_simple_shear\"\nmodel = \"collisional\"\nprogramme = \"acceleration\"\n"
           "rate = 0.0\nacceleration = 50.0\nduration = 3.0\ne0 = " +
           e0 + "\nT0 = 1e-15\nrtol = 1e-8\nmax_steps = 20000\noutputs = 31\n";
  }
  const std::string job_path = dir.write("job.toml", R"(params = "start.toml"
[[free]]
key = "collisional.e_sd"
lower = 0.5
upper = 0.98
[[free]]
key = "collisional.eps_n"
lower = 0.2
upper = 0.95
[[free]]
key = "collisional.V_m"
lower = 0.2
upper = 0.48
[misfit]
scale = "log"
)" + method + exp);
  SynthesisOptions s;
  s.truth = io::load_parameter_set("element_test");
  s.noise = 0.02;
  s.seed = 99;
  synthesize_job_data(job_path, s);
  return job_path;
}

}  // namespace

TEST(CalibrationRoundTrip, CollisionalParametersFromAcceleratedShear) {
  Scratch dir;
  const CalibrationJob job = load_job(collisional_job(dir, R"([algorithm]
global = "GN_CRS2_LM"
global_evaluations = 200
local = "LN_BOBYQA"
local_evaluations = 300
seed = 3
)"));
  Objective obj(job, 0);
  FitOptions fo;
  fo.progress = false;
  const FitResult r = fit(obj, fo);
  expect_recovered(job, r, {{"collisional.e_sd", 0.92}, {"collisional.eps_n", 0.7}, {"collisional.V_m", 0.4}},
                   {"collisional.e_sd", "collisional.eps_n"}, format_report(obj, r));
  std::cout << format_report(obj, r);
}

// The same data by the ensemble method (64 members, 4 iterations, likelihood sd = the 2 % noise):
// the written set (best member, polished) and the posterior median within 3 % of the truth, and
// every 5-95 % interval covering it.
TEST(CalibrationRoundTrip, EnsembleCollisionalParametersFromAcceleratedShear) {
  Scratch dir;
  const CalibrationJob job = load_job(collisional_job(dir, R"([algorithm]
method = "ensemble"
[ensemble]
members = 64
iterations = 4
seed = 2
[likelihood]
relative_sd = 0.02
)"));
  Objective obj(job, 0);
  FitOptions fo;
  fo.progress = false;
  const FitResult r = fit(obj, fo);
  const std::string report = format_report(obj, r);
  ASSERT_TRUE(r.ensemble);
  const std::vector<std::pair<std::string, double>> truth = {
      {"collisional.e_sd", 0.92}, {"collisional.eps_n", 0.7}, {"collisional.V_m", 0.4}};
  for (std::size_t j = 0; j < truth.size(); ++j) {
    ASSERT_EQ(job.free[j].key, truth[j].first);
    const double t = truth[j].second;
    const ParameterSummary& p = r.ensemble->result.summary[j];
    EXPECT_NEAR(r.theta[j], t, 0.03 * t) << truth[j].first << "\n" << report;
    EXPECT_NEAR(p.median, t, 0.03 * t) << truth[j].first << "\n" << report;
    EXPECT_LE(p.q05, t) << truth[j].first << "\n" << report;
    EXPECT_GE(p.q95, t) << truth[j].first << "\n" << report;
  }
  EXPECT_EQ(r.ensemble->result.iterations.back().failed, 0);
  std::cout << r.ensemble->polish << "\n" << format_ensemble_report(obj, r);
}

}  // namespace granflow::calibration::test
