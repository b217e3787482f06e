// Options of the collisional part (issue 25; docs/constitutive.md, "Options of the collisional
// part"): each against its limits and an independent formulation; off, MODEL.md's model.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "reference.hpp"

using namespace granflow;

namespace {

CollisionalParams<double> dem_set(double eps_n, double mu_p) {
  CollisionalParams<double> c;
  c.rho_p = 1;
  c.d = 1;
  c.V_sd = 0.64;
  c.V_m = 0.4;
  c.eps_n = eps_n;
  c.mu_p = mu_p;
  return c;
}

bool same(const KineticCoefficients<double>& a, const KineticCoefficients<double>& b) {
  return a.Vs == b.Vs && a.g0 == b.g0 && a.Gc == b.Gc && a.p_star == b.p_star && a.K_eta == b.K_eta &&
         a.K_kappa == b.K_kappa && a.K_Gamma == b.K_Gamma && a.zeta_U == b.zeta_U && a.clamped == b.clamped;
}

// Steady simple shear by integrating ds/dt with RK4 to steady state, the correlation length
// evaluated at the current s (the exact ODE, not the frozen-coefficient step).
double steady_T_by_rk4(const CollisionalParams<double>& c, double Vs, double rate) {
  const KineticCoefficients<double> kc = kinetic_coefficients(c, Vs);
  const Mat3<double> D = sym(test::simple_shear(rate));
  auto f = [&](double s) { return sqrt_temperature_rate(temperature_balance(c, kc, D, s), s); };
  double s = 1e-3 * rate * c.d, dt = 1e-3 / rate;
  for (int i = 0; i < 400000; ++i) {
    const double k1 = f(s), k2 = f(s + 0.5 * dt * k1), k3 = f(s + 0.5 * dt * k2), k4 = f(s + dt * k3);
    s += dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
  }
  return s * s;
}

}  // namespace

// A neutral value of each option gives MODEL.md's coefficients exactly.
TEST(CollisionalOptions, NeutralValuesReproduceTheDefaultBitForBit) {
  const auto c = test::table2();
  for (double Vs : {0.05, 0.3, 0.5, 0.59}) {
    const auto ref = kinetic_coefficients(c, Vs);
    auto j = c;  // V_sd(mu_p) with V_sd_inf = V_sd: no fall
    j.jamming_friction = true;
    j.V_sd_inf = c.V_sd;
    j.mu_star = 0.1;
    EXPECT_TRUE(same(ref, kinetic_coefficients(j, Vs)));
    EXPECT_EQ(ref.lambda_L, 0.0);
    // restitution use at run time == at compile time
    auto r = c;
    r.restitution = RestitutionUse::DissipationOnly;
    EXPECT_TRUE(same(kinetic_coefficients<RestitutionUse::DissipationOnly>(c, Vs), kinetic_coefficients(r, Vs)));
    EXPECT_FALSE(same(ref, kinetic_coefficients(r, Vs)));
  }
  auto e = c;  // elastic grains: the uniform-shear factor is 1
  e.eps_n = 1;
  e.mu_p = 0;
  auto ed = e;
  ed.dilute_usf = true;
  // (the same A2 with 1/V_s factored differently: equal to rounding)
  EXPECT_NEAR(kinetic_coefficients(ed, 0.2).K_eta / kinetic_coefficients(e, 0.2).K_eta, 1.0, 1e-14);
}

// V_sd(mu_p): V_sd at mu_p = 0, V_sd_inf for mu_p >> mu_star, monotone in between, and g0
// diverges as 2/(V_sd(mu_p) - V_s) at the friction's own jamming fraction.
TEST(CollisionalOptions, JammingFractionFallsWithFrictionAndMovesTheDivergence) {
  auto c = dem_set(0.9, 0.0);
  c.jamming_friction = true;
  c.V_sd_inf = 0.585;
  c.mu_star = 0.1;
  EXPECT_EQ(jamming_fraction(c), 0.64);
  double last = 1;
  for (double mu : {0.0, 0.01, 0.05, 0.1, 0.3, 0.5, 1.0, 10.0}) {
    c.mu_p = mu;
    const double v = jamming_fraction(c);
    EXPECT_LE(v, last);
    EXPECT_NEAR(v, 0.585 + 0.055 * std::exp(-mu / 0.1), 1e-15);
    last = v;
    const double gap = 1e-6;
    EXPECT_NEAR(radial_distribution(v - gap, c.V_m, v) * gap, 2.0, 1e-4);
  }
  EXPECT_NEAR(last, 0.585, 1e-15);
  // the clamp follows: V_s = 0.6 is beyond V_sd(0.5) = 0.5854 but below V_sd(0) = 0.64
  c.mu_p = 0.5;
  EXPECT_TRUE(kinetic_coefficients(c, 0.6).clamped);
  c.mu_p = 0.0;
  EXPECT_FALSE(kinetic_coefficients(c, 0.6).clamped);
}

// With the jamming option the coefficients' g0 diverges at V_sd(mu_p), not at V_sd: g0 of
// Eqs. (25)-(26) written out here with V_sd(mu_p) = V_sd_inf + (V_sd - V_sd_inf) exp(-mu_p / mu_star).
TEST(CollisionalOptions, KineticCoefficientsUseTheJammingFractionOfTheFriction) {
  auto c = dem_set(0.9, 0.3);
  c.jamming_friction = true;
  c.V_sd_inf = 0.585;
  c.mu_star = 0.1;
  const double Vj = 0.585 + (0.64 - 0.585) * std::exp(-0.3 / 0.1);
  for (double Vs : {0.2, 0.45, 0.55, 0.58}) {
    const double g_cs = (2 - Vs) / (2 * std::pow(1 - Vs, 3));
    double g0 = g_cs;
    if (Vs >= c.V_m) {
      const double t = (Vs - c.V_m) / (Vj - c.V_m), f = 1 - t * t;
      g0 = f * g_cs + (1 - f) * 2 / (Vj - Vs);
    }
    const auto kc = kinetic_coefficients(c, Vs);
    EXPECT_NEAR(kc.g0, g0, 1e-12 * g0) << "V_s = " << Vs;
    EXPECT_NEAR(kc.Gc, Vs * g0, 1e-12 * Vs * g0) << "V_s = " << Vs;
    if (Vs > c.V_m) {  // and not that of V_sd = 0.64
      auto off = c;
      off.jamming_friction = false;
      EXPECT_GT(kc.g0, 1.05 * kinetic_coefficients(off, Vs).g0) << "V_s = " << Vs;
    }
  }
}

// Dilute uniform shear: the model's steady T, p and tau with the option over those without it
// equal the Grad-moment solution of uniform shear flow over the Navier-Stokes one, found here by
// solving the steady moment equations for a* = gammadot / nu numerically (bisection):
//   yy: 0 = -beta (P_yy - p) - zeta p,   xy: a* P_yy = -beta P_xy,   trace: -2 a* P_xy = 3 zeta p,
// and the Navier-Stokes balance eta a*^2 = (3/2) zeta p with eta = p / (beta - zeta/2); T ~ 1/a*^2.
TEST(CollisionalOptions, DiluteUniformShearMatchesGradMomentSolution) {
  for (double eps : {0.6, 0.7, 0.9, 0.99}) {
    auto c = dem_set(eps, 0.0);
    const double Vs = 1e-6;
    const auto kt = kinetic_functions(Vs, radial_distribution(Vs, c.V_m, c.V_sd), eps);
    const double beta = kt.nu_eta_star, zeta = kt.zeta0_star;  // g0 = 1 here
    auto bisect = [](const std::function<double(double)>& f) {
      double lo = 1e-6, hi = 100;
      for (int i = 0; i < 200; ++i) {
        const double m = 0.5 * (lo + hi);
        (f(lo) * f(m) <= 0 ? hi : lo) = m;
      }
      return 0.5 * (lo + hi);
    };
    const double p = 1;
    const double a_grad = bisect([&](double a) {
      const double Pyy = p * (1 - zeta / beta), Pxy = -a * Pyy / beta;
      return -2 * a * Pxy - 3 * zeta * p;
    });
    const double a_ns = bisect([&](double a) { return p / (beta - zeta / 2) * a * a - 1.5 * zeta * p; });
    const double T_ratio = (a_ns * a_ns) / (a_grad * a_grad);
    auto on = c;
    on.dilute_usf = true;
    const auto off_ss = steady_simple_shear(c, kinetic_coefficients(c, Vs), 1.0);
    const auto on_ss = steady_simple_shear(on, kinetic_coefficients(on, Vs), 1.0);
    EXPECT_NEAR(on_ss.T / off_ss.T, T_ratio, 1e-5) << eps;
    EXPECT_NEAR(on_ss.p / off_ss.p, T_ratio, 1e-5) << eps;
    EXPECT_NEAR(on_ss.tau / off_ss.tau, std::pow(T_ratio, 1.5), 1e-5) << eps;
    if (eps < 0.95) EXPECT_LT(T_ratio, 0.9);  // a real correction for inelastic grains (0.70 at 0.7)
    // dense (V_s = 0.55): the collisional transfer carries most of the viscosity, the correction fades
    const auto on_d = steady_simple_shear(on, kinetic_coefficients(on, 0.55), 1.0);
    const auto off_d = steady_simple_shear(c, kinetic_coefficients(c, 0.55), 1.0);
    EXPECT_LT(std::fabs(1 - on_d.T / off_d.T), 0.3 * std::fabs(1 - T_ratio) + 1e-12) << eps;
  }
}

// Jenkins' correlation length: the closed-form steady state (L/d = lambda^(2/3) (K_Gamma/K_eta)^(1/3))
// equals the steady state of the temperature ODE integrated with L evaluated at the current T,
// and the frozen-coefficient update of the MPM converges to it. Dilute: L = d, no change; near
// jamming L/d grows as G_c^(2/9).
TEST(CollisionalOptions, CorrelationLengthSteadyStateAgreesWithTheIntegratedBalance) {
  auto c = dem_set(0.7, 0.0);
  c.corr_c = 2.0;
  for (double Vs : {0.45, 0.6, 0.635}) {
    const auto kc = kinetic_coefficients(c, Vs);
    ASSERT_GT(kc.lambda_L, 0);
    const auto ss = steady_simple_shear(c, kc, 2.0);
    const double ell = ss.T / (kc.K_eta / kc.K_Gamma * 4.0);
    if (Vs > 0.6) EXPECT_GT(ell, 1.2) << Vs;  // dense: L > d
    EXPECT_NEAR(steady_T_by_rk4(c, Vs, 2.0) / ss.T, 1.0, 1e-8) << Vs;
    // the model's update, frozen L per step, from the seed temperature
    CollisionalState<double> st{1 / Vs - 1, 1e-7};
    Mat3<double> sig;
    const Mat3<double> L = test::simple_shear(2.0);
    for (int i = 0; i < 20000; ++i) ASSERT_TRUE(collisional_update(c, st, L, 1e-3, sig).ok());
    EXPECT_NEAR(st.s * st.s / ss.T, 1.0, 1e-9) << Vs;
    EXPECT_NEAR(sig(0, 1) / ss.tau, 1.0, 1e-8) << Vs;
  }
  // dilute: G_c -> 0, lambda -> 0, L = d
  const auto dil = kinetic_coefficients(c, 0.001);
  auto off = c;
  off.corr_c = 0;
  EXPECT_EQ(steady_simple_shear(c, dil, 1.0).T, steady_simple_shear(off, kinetic_coefficients(off, 0.001), 1.0).T);
  // near jamming: K_Gamma/K_eta and J tend to constants, lambda ~ G_c^(1/3), so L/d ~ G_c^(2/9)
  auto ell_at = [&](double Vs) {
    const auto kc = kinetic_coefficients(c, Vs);
    return std::make_pair(steady_simple_shear(c, kc, 1.0).T * kc.K_Gamma / kc.K_eta, kc.Gc);
  };
  const auto [l1, g1] = ell_at(0.64 - 1e-3);
  const auto [l2, g2] = ell_at(0.64 - 1e-4 * 1.5);
  EXPECT_NEAR(std::log(l2 / l1) / std::log(g2 / g1), 2.0 / 9.0, 0.01);
}

// Every option at once in the model's update: stiff and seed states stay finite and >= 0, in
// double and float (the MPM's fp32 precision runs the same code).
TEST(CollisionalOptions, AllOptionsKeepTheUpdateFiniteInStiffStates) {
  auto c = dem_set(0.7, 0.5);
  c.rho_p = 2650;
  c.d = 1e-3;
  c.jamming_friction = true;
  c.V_sd_inf = 0.585;
  c.mu_star = 0.05;
  c.corr_c = 0.5;
  c.dilute_usf = true;
  c.restitution = RestitutionUse::DissipationOnly;
  const auto cf = params_cast<float>(c);
  for (double e : {0.7099, 0.75, 1.0, 5.0}) {
    for (double rate : {0.0, 1e-3, 10.0, 1e4}) {
      for (double s0 : {0.0, 1e-8, 1.0}) {
        CollisionalState<double> st{e, s0};
        CollisionalState<float> sf{float(e), float(s0)};
        Mat3<double> sig;
        Mat3<float> sigf;
        const Mat3<double> L = test::simple_shear(rate);
        const Mat3<float> Lf = L.cast<float>();
        for (int i = 0; i < 50; ++i) {
          const UpdateInfo a = collisional_update(c, st, L, 1e-4, sig);
          const UpdateInfo b = collisional_update(cf, sf, Lf, 1e-4f, sigf);
          ASSERT_TRUE(a.ok() && b.ok()) << e << " " << rate << " " << s0;
        }
        EXPECT_TRUE(std::isfinite(st.s) && st.s >= 0 && all_finite(sig));
        EXPECT_TRUE(std::isfinite(sf.s) && sf.s >= 0 && all_finite(sigf));
        if (rate > 0 && st.s > 0) EXPECT_NEAR(sf.s / st.s, 1.0, 1e-3);
      }
    }
  }
}
