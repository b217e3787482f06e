// The fit on steady simple-shear flow curves (closed forms, no element driver): the DEM job,
// independence of the thread count, a synthetic round trip and the identifiability flags.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iostream>
#include <random>
#include <sstream>

#include <granflow/calibration/fit.hpp>
#include <granflow/calibration/job.hpp>
#include <granflow/constitutive.hpp>

#include "helpers.hpp"
#include <granflow/io/parameter_set.hpp>

namespace granflow::calibration::test {

namespace {

FitResult run_fit(const CalibrationJob& job, unsigned threads) {
  Objective obj(job, threads);
  FitOptions fo;
  fo.progress = false;
  return fit(obj, fo);
}

std::size_t index_of(const CalibrationJob& job, const std::string& key) {
  for (std::size_t j = 0; j < job.free.size(); ++j)
    if (job.free[j].key == key) return j;
  ADD_FAILURE() << "no free parameter " << key;
  return 0;
}

// Flow curves p, tau, T against solid fraction from a known collisional set, with relative noise.
std::string synthetic_flow_curves(const CollisionalParams<double>& c, double noise, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::ostringstream os;
  os.precision(12);
  os << "nu,p,s,T\n";
  for (double nu = 0.10; nu < 0.5001; nu += 0.025) {
    const auto kc = kinetic_coefficients(c, nu);
    const auto ss = steady_simple_shear(c, kc, 1.0);
    os << nu << "," << ss.p / c.rho_p * (1 + noise * n01(rng)) << "," << ss.tau / c.rho_p * (1 + noise * n01(rng)) << ","
       << ss.T * (1 + noise * n01(rng)) << "\n";
  }
  return os.str();
}

const char* kSyntheticJob = R"(params = "start.toml"
[[free]]
key = "collisional.e_sd"
lower = 0.3
upper = 0.9
[[free]]
key = "collisional.V_m"
lower = 0.2
upper = 0.48
[[free]]
key = "collisional.eps_n"
lower = 0.3
upper = 0.99
%EXTRA%
[misfit]
scale = "log"
[algorithm]
global = "GN_CRS2_LM"
global_evaluations = 300
local = "LN_BOBYQA"
local_evaluations = 300
seed = 7
[[experiments]]
name = "synthetic"
kind = "steady_shear"
data = "flow.csv"
abscissa = "nu"
quantity = "solid_fraction"
targets = { p = "p", s = "tau", T = "T" }
[experiments.steady_shear]
units = "dimensionless"
)";

std::string synthetic_job(const std::string& extra = "") {
  std::string t = kSyntheticJob;
  t.replace(t.find("%EXTRA%"), 7, extra);
  return t;
}

// Grains of unit density and diameter, e_sd 0.6 (V_sd = 1/1.6), V_m 0.35, eps_n 0.8: the truth of
// the synthetic flow curves.
CollisionalParams<double> unit_grains(double mu_p) {
  CollisionalParams<double> c;
  c.rho_p = 1;
  c.d = 1;
  c.V_sd = 1.0 / 1.6;
  c.V_m = 0.35;
  c.eps_n = 0.8;
  c.mu_p = mu_p;
  return c;
}

}  // namespace

TEST(CalibrationFit, DemFrictionlessFitImprovesAndStaysPhysical) {
  const CalibrationJob job = load_job(source_dir() + "/data/calibration/dem_collisional_mu0.toml");
  ASSERT_EQ(job.experiments.size(), 5u);  // one per restitution value
  const FitResult r = run_fit(job, 0);
  EXPECT_LT(r.at_best.misfit, 0.5 * r.at_start.misfit);
  const double Vsd = r.theta[index_of(job, "collisional.V_sd")], Vm = r.theta[index_of(job, "collisional.V_m")];
  EXPECT_GT(Vsd, 0.60);
  EXPECT_LT(Vsd, 0.66);  // near frictionless random close packing (~0.64)
  EXPECT_GT(Vm, 0.3);
  EXPECT_LT(Vm, 0.5);
  EXPECT_TRUE(r.identifiability.correlated.empty());
  Objective obj(job, 1);
  for (std::size_t c = 0; c < obj.curves().size(); ++c)
    if (obj.curve(c).model_output != "T") EXPECT_GT(r.at_best.curves[c].r2, 0.6) << obj.curve(c).label();
}

TEST(CalibrationFit, ResultDoesNotDependOnTheThreadCount) {
  const CalibrationJob job = load_job(source_dir() + "/data/calibration/dem_collisional_mu05.toml");
  const FitResult a = run_fit(job, 1), b = run_fit(job, 2), c = run_fit(job, 3);
  ASSERT_EQ(a.theta.size(), b.theta.size());
  for (std::size_t j = 0; j < a.theta.size(); ++j) {
    EXPECT_EQ(a.theta[j], b.theta[j]) << job.free[j].key;  // bitwise
    EXPECT_EQ(a.theta[j], c.theta[j]) << job.free[j].key;
  }
  EXPECT_EQ(a.at_best.misfit, b.at_best.misfit);
  EXPECT_EQ(a.evaluations, b.evaluations);
}

TEST(CalibrationFit, FittedSetLoadsUnchanged) {
  Scratch dir;
  const CalibrationJob job = load_job(source_dir() + "/data/calibration/dem_collisional_mu0.toml");
  Objective obj(job, 2);
  FitOptions fo;
  fo.progress = false;
  const FitResult r = fit(obj, fo);
  write_outputs(obj, r, dir.path("out"), false, false);
  const io::ParameterSet s = io::load_parameter_set(dir.path("out/dem_mu0.toml"));
  ASSERT_TRUE(s.collisional);
  EXPECT_DOUBLE_EQ(s.collisional->V_sd, r.theta[index_of(job, "collisional.V_sd")]);
  EXPECT_DOUBLE_EQ(s.collisional->V_m, r.theta[index_of(job, "collisional.V_m")]);
  EXPECT_DOUBLE_EQ(s.collisional->rho_p, job.start.collisional->rho_p);  // untouched values kept
  for (const char* f : {"report.txt", "report_curves.csv", "report_parameters.csv", "correlation.csv", "sensitivity.csv",
                        "curves.csv"})
    EXPECT_TRUE(fs::exists(dir.path(std::string("out/") + f))) << f;
}

// Round trip on the closed forms: curves from a known set with 2 % noise, start 30 % off.
TEST(CalibrationFit, SteadyShearRoundTripRecoversParameters) {
  Scratch dir;
  CollisionalParams<double> truth;
  truth.rho_p = 1;
  truth.d = 1;
  truth.V_sd = 1.0 / (1.0 + 0.60);  // e_sd = 0.60
  truth.V_m = 0.35;
  truth.eps_n = 0.80;
  truth.mu_p = 0.0;
  dir.write("flow.csv", synthetic_flow_curves(truth, 0.02, 3));
  dir.write("start.toml",
            "[collisional]\nrho_p = 1\nd = 1\ne_sd = 0.78\nV_m = 0.455\neps_n = 0.56\nmu_p = 0\n");  // +30 %, +30 %, -30 %
  const CalibrationJob job = load_job(dir.write("job.toml", synthetic_job()));
  Objective obj(job, 2);
  FitOptions fo;
  fo.progress = false;
  const FitResult r = fit(obj, fo);
  expect_recovered(job, r, {{"collisional.e_sd", 0.60}, {"collisional.V_m", 0.35}, {"collisional.eps_n", 0.80}},
                   {"collisional.e_sd", "collisional.eps_n"}, format_report(obj, r));
  std::cout << format_report(obj, r);
}

// eps_n and mu_p enter the kinetic theory only through the effective restitution (Eq. 24):
// freeing both must be flagged as not identifiable.
TEST(CalibrationFit, RestitutionAndFrictionAreFlaggedAsCorrelated) {
  Scratch dir;
  const CollisionalParams<double> truth = unit_grains(0.1);
  dir.write("flow.csv", synthetic_flow_curves(truth, 0.0, 1));
  dir.write("start.toml", "[collisional]\nrho_p = 1\nd = 1\ne_sd = 0.6\nV_m = 0.35\neps_n = 0.8\nmu_p = 0.1\n");
  const CalibrationJob job =
      load_job(dir.write("job.toml", synthetic_job("[[free]]\nkey = \"collisional.mu_p\"\nlower = 0.0\nupper = 0.3\n")));
  Objective obj(job, 1);
  const Identifiability id = identifiability(obj, obj.start_values(), 1e-4);
  const std::size_t je = index_of(job, "collisional.eps_n"), jm = index_of(job, "collisional.mu_p");
  bool flagged = id.singular;
  for (const auto& [a, b] : id.correlated) flagged = flagged || ((a == je && b == jm) || (a == jm && b == je));
  EXPECT_TRUE(flagged);
}

// A linear least-squares problem r = J u - b has the closed-form spread sqrt(s2 (J^T J)^-1_jj),
// s2 = misfit / (N - n). Columns on disjoint rows make J^T J diagonal: sd_j = sqrt(s2 / sum_i J_ij^2).
TEST(CalibrationIdentifiability, GaussNewtonSpreadMatchesTheClosedForm) {
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(8, 2);
  J.block(0, 0, 4, 1).setConstant(2.0);  // sum of squares 16
  J.block(4, 1, 4, 1).setConstant(0.5);  // sum of squares 1
  const double misfit = 0.6, s2 = misfit / 6.0;
  UnitSpread u = gauss_newton_spread(J, misfit);
  EXPECT_NEAR(u.sd[0], std::sqrt(s2 / 16.0), 1e-12);
  EXPECT_NEAR(u.sd[1], std::sqrt(s2 / 1.0), 1e-12);
  EXPECT_NEAR(u.condition, 16.0, 1e-9);
  // correlated columns: J^T J = [[a, c], [c, d]], inverse diagonal d / det and a / det
  J.setZero();
  J.col(0) << 1, 1, 1, 1, 0, 0, 0, 0;
  J.col(1) << 1, 1, 0, 0, 1, 1, 1, 1;
  const double a = 4, c = 2, d = 6, det = a * d - c * c;
  u = gauss_newton_spread(J, misfit);
  EXPECT_NEAR(u.sd[0], std::sqrt(s2 * d / det), 1e-12);
  EXPECT_NEAR(u.sd[1], std::sqrt(s2 * a / det), 1e-12);
  const double disc = std::sqrt((a - d) * (a - d) + 4 * c * c);
  EXPECT_NEAR(u.condition, (a + d + disc) / (a + d - disc), 1e-9);
  // a parameter no residual depends on: undefined spread, infinite condition; the other stays defined
  J.col(1).setZero();
  u = gauss_newton_spread(J, misfit);
  EXPECT_NEAR(u.sd[0], std::sqrt(s2 / 4.0), 1e-12);
  EXPECT_TRUE(std::isnan(u.sd[1]));
  EXPECT_TRUE(std::isinf(u.condition));
}

// End to end: flow curves do not depend on the frictional law, so a free frictional.K0 must be
// reported "not identified" while e_sd and eps_n, which shape the curves (2 % noise), are pinned
// to a small fraction of their ranges; identifiability.csv carries the same verdicts.
TEST(CalibrationIdentifiability, ParameterWithoutEffectIsFlagged) {
  Scratch dir;
  const CollisionalParams<double> truth = unit_grains(0.0);
  dir.write("flow.csv", synthetic_flow_curves(truth, 0.02, 5));
  dir.write("start.toml",
            "[collisional]\nrho_p = 1\nd = 1\ne_sd = 0.6\nV_m = 0.35\neps_n = 0.8\nmu_p = 0\n"
            "[frictional]\nK0 = 150\nnu = 0.22\nn = 0.6\nphi_c_deg = 30\ne_ref = 0.937\nlambda_c = 0.022\n"
            "xi = 0.71\nA_d = 4\nk_p = 0.001\nn_p = 1\nn_d = 1\np_at = 101.3e3\n");
  const CalibrationJob job = load_job(
      dir.write("job.toml", synthetic_job("[[free]]\nkey = \"frictional.K0\"\nlower = 20\nupper = 2000\nlog = true\n")));
  Objective obj(job, 1);
  FitOptions fo;
  fo.progress = false;
  fo.evaluate_only = true;  // at the truth: the spread is that of the noise
  const FitResult r = fit(obj, fo);
  const Identifiability& id = r.identifiability;
  const std::size_t jk = index_of(job, "frictional.K0"), je = index_of(job, "collisional.e_sd"),
                    jn = index_of(job, "collisional.eps_n");
  EXPECT_EQ(id.status[jk], "not identified");
  EXPECT_TRUE(std::isnan(id.sd_range[jk]));
  EXPECT_TRUE(std::isinf(id.condition));
  for (std::size_t j : {je, jn}) {
    EXPECT_EQ(id.status[j], "identified") << job.free[j].key;
    EXPECT_LT(id.sd_range[j], 0.02) << job.free[j].key;
    EXPECT_GT(id.sd_range[j], 0.0) << job.free[j].key;
  }
  const std::string text = format_identifiability(obj, r);
  EXPECT_NE(text.find("not identified"), std::string::npos) << text;
  write_outputs(obj, r, dir.path("out"), false, false);
  std::ifstream in(dir.path("out/identifiability.csv"));
  std::string line, csv;
  std::getline(in, line);
  EXPECT_EQ(line, "key,fitted,lower,upper,log,sd_range,rel_sd,lower_2sd,upper_2sd,correlated_with,condition,status");
  while (std::getline(in, line)) csv += line + "\n";
  EXPECT_NE(csv.find("frictional.K0,150,20,2000,1,,,,,,,not identified"), std::string::npos) << csv;
  EXPECT_NE(csv.find("collisional.e_sd,0.6,0.3,0.9,0,"), std::string::npos) << csv;
}

// The same data and spread, two bounds for eps_n: its standard error in its own units does not
// depend on the range searched (sd_range x range agree), so over [0.3, 0.99] it is identified and
// over [0.799, 0.801] the same spread (~5e-4) is over 10 % of the range: "poorly identified".
TEST(CalibrationIdentifiability, NarrowBoundsMakeTheSameSpreadPoorlyIdentified) {
  Scratch dir;
  const CollisionalParams<double> truth = unit_grains(0.0);
  dir.write("flow.csv", synthetic_flow_curves(truth, 0.02, 5));
  dir.write("start.toml", "[collisional]\nrho_p = 1\nd = 1\ne_sd = 0.6\nV_m = 0.35\neps_n = 0.8\nmu_p = 0\n");
  double sd_abs[2];
  for (int k = 0; k < 2; ++k) {
    std::string t = synthetic_job();
    if (k == 1) t.replace(t.find("lower = 0.3\nupper = 0.99"), 24, "lower = 0.799\nupper = 0.801");
    const CalibrationJob job = load_job(dir.write("job" + std::to_string(k) + ".toml", t));
    Objective obj(job, 1);
    FitOptions fo;
    fo.progress = false;
    fo.evaluate_only = true;
    const FitResult r = fit(obj, fo);
    const std::size_t j = index_of(job, "collisional.eps_n");
    const FreeParameter& p = job.free[j];
    sd_abs[k] = r.identifiability.sd_range[j] * (p.upper - p.lower);
    EXPECT_EQ(r.identifiability.status[j], k == 0 ? "identified" : "poorly identified")
        << "sd_range " << r.identifiability.sd_range[j] << "\n" << format_identifiability(obj, r);
  }
  EXPECT_NEAR(sd_abs[1] / sd_abs[0], 1.0, 0.02);
}

}  // namespace granflow::calibration::test
