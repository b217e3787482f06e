// Collisional part (MODEL.md 4-5) against the reference table of MODEL.md 5.4, closed forms
// transcribed independently here, and exact solutions of the temperature balance.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "reference.hpp"

using namespace granflow;

namespace {

const double kPiD = 3.14159265358979323846;

struct Row {
  const char* set;
  double e0, Vs, V_sd, alpha, g0, Gc, cstar, F, J, Q, zeta0, K_eta, K_Gamma, pstar, Tss, pss, tauss, mu;
};

// MODEL.md 5.4 (computed by the spec's author from the corrected equations).
const std::vector<Row> kTable = {
    {"T2", 0.80, 0.55556, 0.6, 0.435357, 30.472, 16.929, 0.14607, 0.73245, 0.75321, 1.4288, 10.431, 6.3947, 52.313,
     49.598, 0.12224, 3.3683, 2.2358, 0.66377},
    {"T2", 0.85, 0.54054, 0.6, 0.435357, 20.418, 11.037, 0.14607, 0.74033, 0.75957, 1.4288, 6.9894, 4.0905, 33.183,
     32.683, 0.12327, 2.1778, 1.4362, 0.65947},
    {"T2", 0.90, 0.52632, 0.6, 0.435357, 14.994, 7.8918, 0.14607, 0.74936, 0.76719, 1.4288, 5.1329, 2.8765, 23.103,
     23.655, 0.12451, 1.5501, 1.0150, 0.65479},
    {"T2", 0.95, 0.51282, 0.6, 0.435357, 11.685, 5.9921, 0.14607, 0.75940, 0.77609, 1.4288, 3.9999, 2.1528, 17.092,
     18.202, 0.12595, 1.1757, 0.76402, 0.64986},
    {"T3e", 0.99, 0.50251, 1 / 1.92, 0.588877, 80.276, 40.340, 0.05356, 0.80064, 0.87584, 1.5862, 21.959, 16.027,
     90.100, 129.19, 0.17788, 11.548, 6.7595, 0.58535},
    {"T3e", 1.02, 0.49505, 1 / 1.92, 0.588877, 50.225, 24.864, 0.05356, 0.80449, 0.87935, 1.5862, 13.739, 9.7706,
     54.709, 80.011, 0.17859, 7.0739, 4.1291, 0.58370},
    {"T3e", 1.05, 0.48780, 1 / 1.92, 0.588877, 34.630, 16.893, 0.05356, 0.80924, 0.88375, 1.5862, 9.4729, 6.5739,
     36.626, 54.681, 0.17949, 4.7876, 2.7851, 0.58173},
    {"T3c", 0.95, 0.51282, 1 / 1.62, 0.435357, 9.8587, 5.0557, 0.14607, 0.76713, 0.78323, 1.4288, 3.3748, 1.8331,
     14.421, 15.514, 0.12711, 1.0113, 0.65355, 0.64627},
    {"T3f", 0.90, 0.52632, 0.625, 0.435357, 11.135, 5.8607, 0.14607, 0.76034, 0.77694, 1.4288, 3.8118, 2.1633, 17.157,
     17.824, 0.12609, 1.1829, 0.76819, 0.64942},
};

CollisionalParams<double> params_for(const Row& r) {
  CollisionalParams<double> c = test::table2();
  if (std::string(r.set) == "T3e") c = test::table3_element().c;
  if (std::string(r.set) == "T3c") c = test::table3_collapse().c;
  if (std::string(r.set) == "T3f") {
    c = test::table3_collapse().c;
    c.rho_p = 2500;
    c.d = 1e-3;
    c.V_sd = 0.625;
  }
  c.rho_p = 1;  // dimensionless groups: rho_p = d = gammadot = 1
  c.d = 1;
  return c;
}

void expect_rel(double actual, double expected, const char* what, const Row& r) {
  EXPECT_NEAR(actual / expected, 1.0, 2e-4) << what << " set " << r.set << " e0 " << r.e0;
}

}  // namespace

TEST(Collisional, ReferenceTableOfModel54) {
  for (const Row& r : kTable) {
    const auto c = params_for(r);
    const double Vs = 1 / (1 + r.e0);
    EXPECT_NEAR(effective_restitution(c), r.alpha, 1e-6);
    const auto kc = kinetic_coefficients(c, Vs);
    const auto kf = kinetic_functions(Vs, kc.g0, effective_restitution(c));
    expect_rel(kc.g0, r.g0, "g0", r);
    expect_rel(kc.Gc, r.Gc, "Gc", r);
    expect_rel(kf.c_star, r.cstar, "c*", r);
    expect_rel(kf.F, r.F, "F", r);
    expect_rel(kf.J, r.J, "J", r);
    expect_rel(kf.Q, r.Q, "Q", r);
    expect_rel(kf.zeta0_star, r.zeta0, "zeta0*", r);
    expect_rel(kc.K_eta, r.K_eta, "K_eta", r);
    expect_rel(kc.K_Gamma, r.K_Gamma, "K_Gamma", r);
    expect_rel(kc.p_star, r.pstar, "p*", r);
    const auto ss = steady_simple_shear(c, kc, 1.0);
    expect_rel(ss.T, r.Tss, "T_ss", r);
    expect_rel(ss.p, r.pss, "p_ss", r);
    expect_rel(ss.tau, r.tauss, "tau_ss", r);
    expect_rel(ss.mu, r.mu, "mu_c", r);
  }
}

TEST(Collisional, PressureViscositiesAndDissipationFollowEqs20to28) {
  const auto c = test::table2();
  const double a = effective_restitution(c);
  for (double Vs : {0.05, 0.3, 0.45, 0.55}) {
    for (double T : {1e-6, 1e-2, 3.0}) {
      const auto kc = kinetic_coefficients(c, Vs);
      const auto kf = kinetic_functions(Vs, kc.g0, a);
      const double rho = c.rho_p * Vs, s = std::sqrt(T);
      const auto tr = collisional_transport(c, kc, s);
      EXPECT_NEAR(tr.p / (rho * T * (1 + 2 * (1 + a) * kf.Gc)), 1.0, 1e-12);                       // (20)
      EXPECT_NEAR(tr.p / (4 * kf.Gc * kf.F * rho * T), 1.0, 1e-12);                                 // (20)
      EXPECT_NEAR(tr.eta / (8 / (5 * std::sqrt(kPiD)) * kf.Gc * kf.J * rho * c.d * s), 1.0, 1e-12);  // (21)
      EXPECT_NEAR(tr.kappa / (4 / (3 * std::sqrt(kPiD)) * kf.Gc * kf.Q * rho * c.d * s), 1.0, 1e-12);  // (22)
      const double eta0 = 5 * std::sqrt(kPiD) / 96 * c.rho_p * c.d * s;
      EXPECT_NEAR(tr.eta / (eta0 * kf.eta_star), 1.0, 1e-12);
      EXPECT_NEAR(tr.kappa / (eta0 * kf.kappa_star), 1.0, 1e-12);
      // (28): Gamma = 144/(5 sqrt(pi)) rho T^1.5 zeta0* / (d (1 + e))
      const double Gamma = 144 / (5 * std::sqrt(kPiD)) * rho * T * s * kf.zeta0_star * Vs / c.d;
      EXPECT_NEAR(c.rho_p * kc.K_Gamma * s * s * s / c.d / Gamma, 1.0, 1e-12);
    }
  }
}

TEST(Collisional, ShearViscosityMatchesBerziClosedFormWhenCstarVanishes) {
  // c* = 0 at alpha = 1/sqrt(2); then A2, A4-A8 reduce to Berzi's J (MODEL.md 4.3).
  const double a = 1 / std::sqrt(2.0);
  for (double Vs : {0.2, 0.45, 0.55}) {
    const double g0 = radial_distribution(Vs, 0.4, 0.6);
    const auto kf = kinetic_functions(Vs, g0, a);
    ASSERT_NEAR(kf.c_star, 0.0, 1e-14);
    const double G = kf.Gc;
    const double J = (1 + a) / 2 + kPiD / 32 * (5 + 2 * (1 + a) * (3 * a - 1) * G) * (5 + 4 * (1 + a) * G) /
                                       ((24 - 6 * (1 - a) * (1 - a) - 5 * (1 - a * a)) * G * G);
    EXPECT_NEAR(kf.J / J, 1.0, 1e-12);
    EXPECT_NEAR(kf.Q, 1 + a, 1e-12);  // Q = (1 + alpha)(1 - c*/32)
  }
}

TEST(Collisional, RadialDistributionBranches) {
  const double Vm = 0.4, Vsd = 0.6;
  const double below = radial_distribution(Vm - 1e-12, Vm, Vsd), above = radial_distribution(Vm + 1e-12, Vm, Vsd);
  EXPECT_NEAR(below, above, 1e-9);
  // Carnahan-Starling below V_m
  EXPECT_NEAR(radial_distribution(0.3, Vm, Vsd), (2 - 0.3) / (2 * std::pow(0.7, 3)), 1e-14);
  // divergence 2/(V_sd - V_s)
  for (double gap : {1e-3, 1e-5, 1e-7}) EXPECT_NEAR(radial_distribution(Vsd - gap, Vm, Vsd) * gap, 2.0, 30 * gap);
  // dilute limit: g0 -> 1, p_c -> rho_p V_s T (ideal gas)
  const auto c = test::table2();
  const auto kc = kinetic_coefficients(c, 1e-8);
  EXPECT_NEAR(kc.g0, 1.0, 1e-7);
  EXPECT_NEAR(collisional_transport(c, kc, 1.0).p / (c.rho_p * 1e-8), 1.0, 1e-6);
  const double eta_dilute = collisional_transport(c, kc, 1.0).eta;
  EXPECT_TRUE(std::isfinite(eta_dilute));
  EXPECT_NEAR(eta_dilute / collisional_transport(c, kinetic_coefficients(c, 1e-6), 1.0).eta, 1.0, 1e-4);
}

TEST(Collisional, ClampBelowRandomClosePacking) {
  auto c = test::table2();
  c.vs_gap = 1e-7;
  const auto kc = kinetic_coefficients(c, 0.6 - 1e-9);
  EXPECT_TRUE(kc.clamped);
  EXPECT_NEAR(kc.Vs, 0.6 - 1e-7, 1e-15);
  EXPECT_FALSE(kinetic_coefficients(c, 0.55).clamped);
}

namespace {

RiccatiCoefficients<double> shear_balance(const CollisionalParams<double>& c, double Vs, double rate) {
  return temperature_balance(c, kinetic_coefficients(c, Vs), Mat3<double>(sym(test::simple_shear(rate))), 0.0);
}

}  // namespace

TEST(Collisional, ExactSolutionOfConstantRateShearForAnyStep) {
  // MODEL.md 5.3: s(t) = s_inf tanh(t/tau + artanh(s0/s_inf)).
  const auto c = test::table2();
  const double Vs = 1 / 1.8, rate = 10.0;
  const auto kc = kinetic_coefficients(c, Vs);
  const double s_inf = c.d * rate * std::sqrt(kc.K_eta / kc.K_Gamma);
  const double tau = 3 * Vs / (rate * std::sqrt(kc.K_eta * kc.K_Gamma));
  EXPECT_NEAR(tau, 9.11e-3, 0.01e-3);  // MODEL.md 5.4 example
  EXPECT_NEAR(s_inf * s_inf, 1.2224e-5, 0.0001e-5);
  const auto r = shear_balance(c, Vs, rate);
  const double s0 = std::sqrt(1e-15);
  for (double dt : {1e-9, 1e-6, 1e-3, 1e-2, 0.1, 1.0}) {
    const double exact = s_inf * std::tanh(dt / tau + std::atanh(s0 / s_inf));
    const double s = advance_sqrt_temperature(r, s0, dt);
    EXPECT_NEAR(s / exact, 1.0, 1e-10) << "dt = " << dt;
  }
  // cooling from above the steady state
  const double s_hot = 3 * s_inf, t = 0.02;
  const double exact = s_inf / std::tanh(t / tau + std::atanh(s_inf / s_hot));  // coth branch
  EXPECT_NEAR(advance_sqrt_temperature(r, s_hot, t) / exact, 1.0, 1e-10);
}

TEST(Collisional, HaffCoolingWithoutShear) {
  const auto c = test::table2();
  const double Vs = 0.5;
  const auto kc = kinetic_coefficients(c, Vs);
  const auto r = temperature_balance(c, kc, Mat3<double>::Zero(), 0.0);
  const double b = kc.K_Gamma / (3 * Vs * c.d), s0 = 0.1;
  for (double t : {1e-4, 1e-2, 1.0, 100.0}) EXPECT_NEAR(advance_sqrt_temperature(r, s0, t), s0 / (1 + b * s0 * t), 1e-14);
}

TEST(Collisional, FrozenCoefficientUpdateMatchesRK4WithVolumeChange) {
  // Compression (tr D < 0) and expansion make B non-zero: compare with a fine RK4 of ds/dt = A - B s - C s^2.
  const auto c = test::table2();
  for (double trD : {-5.0, 3.0}) {
    Mat3<double> D = sym(test::simple_shear(20.0));
    D.diagonal().setConstant(trD / 3);
    const auto r = temperature_balance(c, kinetic_coefficients(c, 0.5), D, 0.0);
    ASSERT_NE(r.B, 0.0);
    for (double s0 : {0.0, 1e-3, 0.05}) {
      const double T = 0.05;
      const int n = 200000;
      const double h = T / n;
      double s = s0;
      auto f = [&](double x) { return sqrt_temperature_rate(r, x); };
      for (int i = 0; i < n; ++i) {
        const double k1 = f(s), k2 = f(s + 0.5 * h * k1), k3 = f(s + 0.5 * h * k2), k4 = f(s + h * k3);
        s += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
      }
      EXPECT_NEAR(advance_sqrt_temperature(r, s0, T), s, 1e-10 + 1e-9 * s) << "trD " << trD << " s0 " << s0;
    }
  }
}

TEST(Collisional, TemperatureStaysNonNegativeAndFiniteInStiffCases) {
  auto c = test::table2();
  c.vs_gap = 1e-7;
  for (double Vs : {0.3, 0.55, 0.6 - 1e-6, 0.6 - 2e-7}) {
    for (double rate : {0.0, 1e-3, 10.0, 1e4}) {
      for (double trD : {-100.0, 0.0, 100.0}) {
        Mat3<double> D = sym(test::simple_shear(rate));
        D.diagonal().setConstant(trD / 3);
        const auto r = temperature_balance(c, kinetic_coefficients(c, Vs), D, 0.0);
        for (double dt : {1e-9, 1e-7, 1e-5, 1e-3, 1e-1, 1.0}) {
          for (double s0 : {0.0, std::sqrt(1e-15), 1.0}) {
            const double s = advance_sqrt_temperature(r, s0, dt);
            ASSERT_TRUE(std::isfinite(s)) << Vs << " " << rate << " " << dt;
            ASSERT_GE(s, 0.0);
          }
        }
      }
    }
  }
}

TEST(Collisional, ElasticGrainsHaveNoDissipation) {
  // eps_n = 1, mu_p = 0: alpha = 1, K_Gamma = 0, and s grows linearly under shear: s = s0 + A t.
  auto c = test::table2();
  c.eps_n = 1.0;
  c.mu_p = 0.0;
  const auto r = shear_balance(c, 0.5, 10.0);
  EXPECT_EQ(r.C, 0.0);
  EXPECT_NEAR(advance_sqrt_temperature(r, 1e-3, 0.5), 1e-3 + r.A * 0.5, 1e-14);
}

TEST(Collisional, SteadyShearBalancesProductionAndDissipationWithBagnoldScaling) {
  const auto c0 = test::table2();
  const double Vs = 1 / 1.85;
  double ref_p = 0, ref_tau = 0;
  for (double d : {1e-3, 2e-3}) {
    for (double rate : {1.0, 10.0, 100.0}) {
      auto c = c0;
      c.d = d;
      CollisionalState<double> st{0.85, std::sqrt(1e-15)};
      Mat3<double> sig;
      const double tau = 3 * Vs / (rate * std::sqrt(kinetic_coefficients(c, Vs).K_eta * kinetic_coefficients(c, Vs).K_Gamma));
      const double dt = tau / 50;
      for (int k = 0; k < 2000; ++k) ASSERT_TRUE(collisional_update(c, st, test::simple_shear(rate), dt, sig).ok());
      // production eta gammadot^2 equals dissipation Gamma at the steady state
      const auto kc = kinetic_coefficients(c, Vs);
      const auto t = collisional_transport(c, kc, st.s);
      const double Gamma = c.rho_p * kc.K_Gamma * st.s * st.s * st.s / c.d;
      EXPECT_NEAR(t.eta * rate * rate / Gamma, 1.0, 1e-9);
      const double scale = c.rho_p * d * d * rate * rate;
      const double p = -sig(1, 1) / scale, tau_xy = sig(0, 1) / scale;
      if (ref_p == 0) {
        ref_p = p;
        ref_tau = tau_xy;
        EXPECT_NEAR(p, 2.1778, 2e-4 * 2.1778);  // MODEL.md 5.4, Table 2 e0 = 0.85
      }
      EXPECT_NEAR(p / ref_p, 1.0, 1e-9);
      EXPECT_NEAR(tau_xy / ref_tau, 1.0, 1e-9);
    }
  }
}

TEST(Collisional, RestitutionOnlyInDissipationIsSelectableAtCompileTime) {
  const auto c = test::table2();
  const auto everywhere = kinetic_coefficients<RestitutionUse::Everywhere>(c, 0.5);
  const auto diss_only = kinetic_coefficients<RestitutionUse::DissipationOnly>(c, 0.5);
  EXPECT_EQ(everywhere.K_Gamma, diss_only.K_Gamma);  // cooling uses the effective restitution in both
  // transport coefficients use eps_n = 0.6 instead of alpha = 0.435: p* = 1 + 2 (1 + eps_n) Gc
  EXPECT_NEAR(diss_only.p_star, 1 + 2 * 1.6 * diss_only.Gc, 1e-12);
  EXPECT_NE(everywhere.K_eta, diss_only.K_eta);
}
