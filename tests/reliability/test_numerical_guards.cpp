// Numerical guards of the element driver: non-finite or inadmissible states are reported with
// the time, the quantity and its value instead of propagating NaN into the results.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

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
