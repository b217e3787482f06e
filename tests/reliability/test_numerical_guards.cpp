// Numerical guards of the element driver: non-finite or inadmissible states, and results outside
// the yield surface, are reported with the time, the quantity and its value instead of
// propagating NaN or an impossible stress into the results.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include <granflow/elementtest/paper.hpp>
#include <granflow/elementtest/run.hpp>

#include "guards.hpp"

using namespace granflow;
namespace gt = granflow::elementtest;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

Mat3<double> iso(double p) { return -p * Mat3<double>::Identity(); }

std::string issue(const Mat3<double>& sf, double eps_pd, double e, double s, double floor = -1.0) {
  return gt::detail::inadmissible_state(sf, eps_pd, e, s, 0.1, 0.0, 0.0, floor);
}

void expect_has(const std::string& text, const std::string& part) {
  EXPECT_NE(text.find(part), std::string::npos) << "'" << part << "' not in: " << text;
}

std::string run_error(gt::ElementTest t, const std::string& set) {
  try {
    gt::run_element_test(t, io::load_parameter_set(set));
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

// Isotropic compression at rate r: e(t) = (1 + e0) exp(-3 r t) - 1 reaches 0 at ln(1 + e0) / (3 r).
gt::ElementTest compress_to_zero_voids(gt::SolverKind solver) {
  gt::ElementTest t;
  t.name = "to_zero_voids";
  t.path = gt::LoadingPath::Isotropic;
  t.model = gt::ModelChoice::Frictional;
  t.programme.rate = 1.0;
  t.programme.duration = 1.0;
  t.initial.e0 = 0.9;
  t.initial.sigma_v0 = 1000;
  t.output.points = 11;
  t.solver.kind = solver;
  t.solver.dt = 1e-3;
  return t;
}

// Triaxial compression (sigma_yy the major compression) of mean pressure p and deviator q.
Mat3<double> triaxial(double p, double q) {
  Mat3<double> s = iso(p);
  s(1, 1) -= 2.0 * q / 3.0;
  s(0, 0) += q / 3.0;
  s(2, 2) += q / 3.0;
  return s;
}

// Issue 21: Fig. 4's e0 = 0.80 test with a cone of opening ~3.5e-8 (phi_c = 1e-6 degrees) and
// nu -> -1 (G / K ~ 4.5e6), as `granflow element data/tests/fig4_e080.toml --set ...` runs it.
gt::ElementTest narrow_cone_test(io::ParameterSet& set) {
  set = io::load_parameter_set("frictional_element");
  for (const char* o : {"frictional.K0=120", "frictional.nu=-0.999999", "frictional.n=0", "frictional.phi_c_deg=1e-6"})
    io::apply_override(set, o);
  gt::ElementTest t = gt::paper::fig4_test(0.80);
  t.output.points = 31;
  return t;
}

}  // namespace

TEST(Guards, AdmissibleStatePasses) { EXPECT_EQ(issue(iso(100), 0.01, 0.9, 0.1), ""); }

TEST(Guards, VoidRatioOutOfRangeIsNamedWithValueAndRange) {
  const std::string a = issue(iso(100), 0, 0.0, 0.1);
  expect_has(a, "e = 0");
  expect_has(a, "allowed: 0 < e < 2.97");
  expect_has(issue(iso(100), 0, 3.1, 0.1), "e = 3.1");
  expect_has(issue(iso(100), 0, kNaN, 0.1), "e = nan");
}

TEST(Guards, NegativeTemperatureIsNamed) {
  const std::string a = issue(iso(100), 0, 0.9, -0.5);
  expect_has(a, "T < 0");
  expect_has(a, "-0.5");
  EXPECT_EQ(gt::detail::inadmissible_state(iso(100), 0, 0.9, -1e-12, 0, 0, 0, -1, -1e-11), "");  // integration error
  expect_has(issue(iso(100), 0, 0.9, kInf), "T = inf");
}

TEST(Guards, NonFiniteStressAndStrainAreNamed) {
  Mat3<double> s = iso(100);
  s(0, 1) = s(1, 0) = kNaN;
  expect_has(issue(s, 0, 0.9, 0.1), "sigma_f_xy = nan Pa");
  expect_has(issue(iso(100), kInf, 0.9, 0.1), "eps_pd = inf");
}

TEST(Guards, PressureFarBelowTensionCutoffIsNamed) {
  const std::string a = issue(iso(-50), 0, 0.9, 0.1, -1.0);
  expect_has(a, "p_f = -50 Pa");
  expect_has(a, "tension cut-off");
  EXPECT_EQ(issue(iso(-0.5), 0, 0.9, 0.1, -1.0), "");  // within the event tolerance
}

TEST(Guards, UpdateFlagsInWords) {
  expect_has(gt::detail::update_flags_text(info::kNonFinite), "non-finite");
  expect_has(gt::detail::update_flags_text(info::kInadmissible | info::kNonFinite), "inadmissible input state");
}

// Driven to zero voids: CVODE stops where e reaches 0 and says so (time, e), no NaN rows.
TEST(Guards, CvodeReportsWhereTheVoidRatioVanished) {
  const std::string e = run_error(compress_to_zero_voids(gt::SolverKind::Cvode), "frictional_element");
  ASSERT_FALSE(e.empty()) << "no error";
  expect_has(e, "at t = 0.21395");  // ln(1.9) / 3 = 0.2139513
  expect_has(e, "e = ");
  expect_has(e, "allowed: 0 < e < 2.97");
}

TEST(Guards, IncrementalReportsWhereTheVoidRatioVanished) {
  const std::string e = run_error(compress_to_zero_voids(gt::SolverKind::Incremental), "frictional_element");
  ASSERT_FALSE(e.empty()) << "no error";
  expect_has(e, "at t = 0.213");
  expect_has(e, "inadmissible input state");
  expect_has(e, "e = 0.00");
}

// Up to just before that time the results are finite.
TEST(Guards, ResultsBeforeTheLimitAreFinite) {
  gt::ElementTest t = compress_to_zero_voids(gt::SolverKind::Cvode);
  t.programme.duration = 0.2;
  const gt::ResultTable r = gt::run_element_test(t, io::load_parameter_set("frictional_element"));
  for (const auto& c : r.columns)
    for (double v : c) EXPECT_TRUE(std::isfinite(v));
  EXPECT_NEAR(r.column("e").back(), 1.9 * std::exp(-0.6) - 1.0, 1e-4);
}

// The yield-surface guard: f = q / p - g M_p h is linear in q at fixed p and Lode angle, so the
// surface and the tolerance band lie at known q.
TEST(Guards, StressOutsideTheYieldSurfaceIsNamedWithTheAllowedRatio) {
  const FrictionalParams<double> mp = *io::load_parameter_set("frictional_element").frictional;
  constexpr LodeShape kL = LodeShape::SmoothMohrCoulomb;
  const double p = 1e5, e = 0.8, eps_pd = 0.01;
  const double tol = gt::detail::yield_guard_tolerance(mp);
  EXPECT_DOUBLE_EQ(tol, 100 * mp.ftol + 1e-6);  // frictional_increment's band "on the surface"
  const YieldState<double> y = yield_state<kL>(mp, triaxial(p, 1.0), eps_pd, e, Mat3<double>::Zero());
  const double r_surface = y.Gm * y.h;
  auto outside = [&](double r) { return gt::detail::outside_yield_surface<kL>(mp, triaxial(p, r * p), eps_pd, e); };
  EXPECT_EQ(outside(0.5 * r_surface), "");
  EXPECT_EQ(outside(r_surface), "");
  EXPECT_EQ(outside(r_surface + 0.9 * tol), "");  // just inside the tolerance
  const std::string a = outside(r_surface + 1.1 * tol);
  expect_has(a, "lies outside the yield surface");
  expect_has(a, "at p_f = 100000 Pa");
  expect_has(a, "q_f = ");
  expect_has(a, "q_f / p_f = ");
  expect_has(a, "allowed: <= g M_p h + tol");
  expect_has(a, "1.1e-06");
  expect_has(outside(10.0), "q_f = 1000000 Pa");
}

// Below p_min the ratio is taken at p_min, as the library's rounded apex does.
TEST(Guards, YieldGuardBelowThePressureFloorUsesPmin) {
  const FrictionalParams<double> mp = *io::load_parameter_set("frictional_element").frictional;
  const double p = 0.5 * mp.p_min;
  expect_has(gt::detail::outside_yield_surface<LodeShape::SmoothMohrCoulomb>(mp, triaxial(p, 10 * p), 0.01, 0.8),
             "q_f / p_min = ");
  EXPECT_EQ(gt::detail::outside_yield_surface<LodeShape::SmoothMohrCoulomb>(mp, Mat3<double>::Zero(), 0.01, 0.8), "");
}

// The issue's case. CVODE used to integrate elastically far past the narrow cone (q_f = 7.4e13 Pa
// at p_f = 1e5 Pa; with the guard alone, row 2 was refused): a plastic phase ended with f above
// the onset offset, so the elastic phase after it had no yield crossing to find. Now it flows on
// the cone: every row passes the guard, and q_f agrees with the incremental update (~0.004 Pa)
// within the guard's tolerance (CVODE's stress tolerance, rtol sigma_ref = 0.1 Pa, exceeds the
// cone's width, and the projection skips q_f <= 1e-6 p_f).
TEST(Guards, NarrowConeStaysOnTheSurfaceUnderCvodeAndIncremental) {
  io::ParameterSet set;
  gt::ElementTest t = narrow_cone_test(set);
  const gt::ResultTable cvode = gt::run_element_test(t, set);
  t.solver.kind = gt::SolverKind::Incremental;
  t.solver.dt = 1e-4;
  const gt::ResultTable incremental = gt::run_element_test(t, set);
  const double tol = gt::detail::yield_guard_tolerance(*set.frictional);
  EXPECT_LT(incremental.column("q_f").back(), 0.005);
  EXPECT_NEAR(incremental.column("p_f").back(), 1e5, 1.0);
  EXPECT_NEAR(cvode.column("q_f").back(), incremental.column("q_f").back(), tol * 1e5);
  EXPECT_GT(cvode.column("eps_pd").back(), 0.1);  // it flowed plastically
  EXPECT_LT(cvode.stats.events, 10);
}
