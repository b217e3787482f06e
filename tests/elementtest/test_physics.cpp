// Physics of the element tests: exact solutions, scaling laws, the trends of the source's figures.
#include <cstdio>

#include "common.hpp"

using namespace granflow;

// MODEL 5.3: constant-rate, constant-volume shear of the collisional model has the exact
// solution s(t) = s_inf tanh(t / tau + artanh(s0 / s_inf)).
TEST(ElementPhysics, CvodeMatchesExactTanhSolution) {
  const ParameterSet set = pset("collisional_element");
  gt::ElementTest t;
  t.model = gt::ModelChoice::Collisional;
  t.programme.rate = 10.0;
  t.programme.duration = 0.05;
  t.initial.e0 = 0.80;
  t.initial.T0 = 1e-15;
  t.solver.rtol = 1e-9;
  t.solver.atol = 1e-12;
  t.output.points = 51;
  const gt::ResultTable r = gt::run_element_test(t, set);
  const auto kc = kinetic_coefficients(*set.collisional, 1.0 / 1.8);
  const double d = set.collisional->d, g = 10.0, Vs = 1.0 / 1.8;
  const double s_inf = d * g * std::sqrt(kc.K_eta / kc.K_Gamma);
  const double tau = 3 * Vs / (g * std::sqrt(kc.K_eta * kc.K_Gamma));
  EXPECT_NEAR(tau, 9.11e-3, 0.01e-3);  // MODEL 5.4 relaxation-time example
  double worst = 0;
  for (std::size_t i = 1; i < r.rows(); ++i) {
    const double s_exact = s_inf * std::tanh(r.column("time")[i] / tau + std::atanh(std::sqrt(1e-15) / s_inf));
    worst = std::max(worst, std::fabs(std::sqrt(r.column("T")[i]) - s_exact) / s_inf);
  }
  EXPECT_LT(worst, 1e-6);
}

// Bagnold scaling: steady stresses proportional to gammadot^2, equal to the closed form.
TEST(ElementPhysics, SteadySweepFollowsBagnoldScaling) {
  const ParameterSet set = pset("collisional_element");
  gt::ElementTest t;
  t.model = gt::ModelChoice::Collisional;
  t.programme.kind = gt::ProgrammeKind::Sweep;
  t.programme.sweep_rates = {0.1, 1.0, 10.0, 100.0};
  t.programme.sweep_strain = 5.0;
  t.initial.e0 = 0.85;
  const gt::ResultTable r = gt::run_element_test(t, set);
  const auto kc = kinetic_coefficients(*set.collisional, 1.0 / 1.85);
  for (std::size_t i = 0; i < r.rows(); ++i) {
    const double g = r.column("shear_rate")[i];
    const auto ss = steady_simple_shear(*set.collisional, kc, g);
    EXPECT_NEAR(r.column("tau")[i] / ss.tau, 1.0, 1e-4) << g;
    EXPECT_NEAR(r.column("sigma_n")[i] / ss.p, 1.0, 1e-4) << g;
    // MODEL 5.4: tau / (rho_p d^2 gammadot^2) = 1.4362 for e0 = 0.85
    EXPECT_NEAR(r.column("tau")[i] / (1500 * 1e-6 * g * g), 1.4362, 2e-4);
  }
}

// Fig. 4: the stress at gamma = 0.3 falls with e0; e0 = 0.95 liquefies; e0 = 0.90 softens then hardens.
TEST(ElementPhysics, Fig4OrderingSofteningAndLiquefaction) {
  const ParameterSet set = pset("frictional_element");
  double prev = 1e300;
  for (double e0 : {0.80, 0.85, 0.90, 0.95}) {
    const gt::ResultTable r = gt::run_element_test(gt::paper::fig4_test(e0), set);
    expect_admissible(r);
    EXPECT_LT(last(r, "tau"), prev) << e0;
    prev = last(r, "tau");
    const auto& tau = r.column("tau");
    const std::size_t ipk = std::max_element(tau.begin(), tau.begin() + 20) - tau.begin();  // early peak
    const double tmin = *std::min_element(tau.begin() + ipk, tau.end());
    if (e0 == 0.90) {
      EXPECT_LT(tmin, 0.2 * tau[ipk]);         // softens ...
      EXPECT_GT(tau.back(), 3 * tau[ipk]);     // ... then hardens
      EXPECT_FALSE(r.stats.tension_cutoff);
    }
    if (e0 == 0.95) {
      EXPECT_TRUE(r.stats.tension_cutoff);     // static liquefaction: no residual strength
      EXPECT_EQ(last(r, "tau"), 0.0);
    }
  }
}

// Fig. 5: stresses rise with rate; lower e0 gives higher stress.
TEST(ElementPhysics, Fig5StressRisesWithRateAndDensity) {
  const ParameterSet set = pset("collisional_element");
  double prev = 1e300;
  for (double e0 : {0.80, 0.85, 0.90, 0.95}) {
    const gt::ResultTable r = gt::run_element_test(gt::paper::fig5_test(e0), set);
    expect_admissible(r);
    const auto& tau = r.column("tau");
    for (std::size_t i = 20; i < tau.size(); ++i) ASSERT_GT(tau[i], tau[i - 1]);
    EXPECT_LT(last(r, "sigma_n"), prev);
    prev = last(r, "sigma_n");
  }
}

// Fig. 6/7: with e0 > e_ref the frictional stress vanishes at gamma ~ 0.004 (MODEL 8); at a
// fixed small strain the frictional part dominates at the lowest rates, the collisional at the highest.
TEST(ElementPhysics, Fig7FrictionalAtLowRatesCollisionalAtHighRates) {
  const ParameterSet set = pset("element_test");
  const gt::ResultTable f6 = gt::run_element_test(gt::paper::fig6_test(1.10), set);
  ASSERT_TRUE(f6.stats.tension_cutoff);
  EXPECT_NEAR(10.0 * f6.stats.cutoff_time, 0.004, 0.001);  // gamma at which p_f reaches 0
  EXPECT_EQ(last(f6, "tau_f"), 0.0);
  const gt::ResultTable r = gt::run_element_test(gt::paper::fig7_fixed_strain_sweep(1.10, 0.002), set);
  expect_admissible(r);
  EXPECT_LT(r.column("K_col").front(), 1e-6);
  EXPECT_GT(r.column("K_col").back(), 0.9);
  EXPECT_GT(r.column("tau_f").front(), 1.0);
}

// Fig. 6: lower e0 gives higher stress at the end of the protocol.
TEST(ElementPhysics, Fig6OrderingOfVoidRatios) {
  const ParameterSet set = pset("element_test");
  double prev = 1e300;
  for (double e0 : {0.99, 1.02, 1.05}) {
    const gt::ResultTable r = gt::run_element_test(gt::paper::fig6_test(e0), set);
    expect_admissible(r);
    EXPECT_LT(last(r, "tau"), prev);
    prev = last(r, "tau");
    EXPECT_NEAR(last(r, "shear_rate"), 985.0, 1e-9);
  }
}

double max_rel_diff(const gt::ResultTable& a, const gt::ResultTable& b, const std::string& c) {
  double scale = 0, d = 0;
  for (double v : b.column(c)) scale = std::max(scale, std::fabs(v));
  for (std::size_t i = 0; i < a.rows(); ++i) d = std::max(d, std::fabs(a.column(c)[i] - b.column(c)[i]));
  return d / scale;
}

// The MPM's incremental update and CVODE agree.
TEST(ElementPhysics, CvodeAndIncrementalAgree) {
  {
    const ParameterSet set = pset("frictional_element");
    gt::ElementTest t = gt::paper::fig4_test(0.80);
    t.output.points = 31;
    const gt::ResultTable a = gt::run_element_test(t, set);
    t.solver.kind = gt::SolverKind::Incremental;
    t.solver.dt = 1e-4;
    const gt::ResultTable b = gt::run_element_test(t, set);
    EXPECT_LT(max_rel_diff(b, a, "tau"), 2e-3);
    EXPECT_LT(max_rel_diff(b, a, "sigma_n"), 2e-3);
  }
  {
    const ParameterSet set = pset("element_test");
    gt::ElementTest t = gt::paper::fig6_test(0.99);
    t.output.points = 40;
    const gt::ResultTable a = gt::run_element_test(t, set);
    t.solver.kind = gt::SolverKind::Incremental;
    t.solver.dt = 1e-3;
    const gt::ResultTable b = gt::run_element_test(t, set);
    EXPECT_LT(max_rel_diff(b, a, "tau"), 1e-3);
    EXPECT_LT(max_rel_diff(b, a, "sigma_n"), 1e-3);
  }
}

// Convergence order of the incremental update in a smooth case: collisional-only shear under
// constant acceleration (Fig. 5). The frozen-coefficient Riccati update is exact for constant
// coefficients; with the rate sampled at the step midpoint the remaining error is that of the
// midpoint rule on A(t) ~ gammadot(t)^2: theoretical order 2.
TEST(ElementPhysics, IncrementalUpdateIsSecondOrder) {
  const ParameterSet set = pset("collisional_element");
  gt::ElementTest t = gt::paper::fig5_test(0.80);
  t.programme.duration = 0.2;  // the transient (relaxation time ~ 10 ms at 10 1/s)
  t.output.points = 11;
  t.solver.rtol = 1e-11;
  t.solver.atol = 1e-14;
  const gt::ResultTable ref = gt::run_element_test(t, set);
  t.solver.kind = gt::SolverKind::Incremental;
  std::vector<double> err;
  for (double dt : {4e-3, 2e-3, 1e-3}) {
    t.solver.dt = dt;
    err.push_back(max_rel_diff(gt::run_element_test(t, set), ref, "tau"));
  }
  const double order = std::log2(err[1] / err[2]);
  std::printf("incremental update, Fig. 5 case: errors %.3e %.3e %.3e at dt 4e-3 2e-3 1e-3, orders %.3f %.3f\n", err[0],
              err[1], err[2], std::log2(err[0] / err[1]), order);
  EXPECT_NEAR(order, 2.0, 0.2) << err[0] << " " << err[1] << " " << err[2];
  EXPECT_NEAR(std::log2(err[0] / err[1]), 2.0, 0.2);
}
