// Parameter sets of MODEL.md 7 typed in for the tests (independent of the TOML loader).
#pragma once

#include <granflow/constitutive.hpp>

namespace granflow::test {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

inline FrictionalParams<double> table1() {
  FrictionalParams<double> f;
  f.K0 = 150; f.nu = 0.22; f.n = 0.6; f.phi_c = 30 * kDeg; f.e_ref = 0.937; f.lambda_c = 0.022; f.xi = 0.71;
  f.A_d = 4; f.k_p = 0.001; f.n_p = 1; f.n_d = 1;
  return f;
}

inline CollisionalParams<double> table2() {
  CollisionalParams<double> c;
  c.rho_p = 1500; c.d = 1e-3; c.V_sd = 0.6; c.V_m = 0.4; c.eps_n = 0.6; c.mu_p = 0.2;
  return c;
}

inline PhaseTransitionParams<double> table3_element() {
  PhaseTransitionParams<double> p;
  p.c.rho_p = 1050; p.c.d = 1e-3; p.c.V_sd = 1.0 / 1.92; p.c.V_m = 0.4; p.c.eps_n = 0.7; p.c.mu_p = 0.1;
  p.f.K0 = 120; p.f.nu = 0.235; p.f.n = 0.5; p.f.phi_c = 23 * kDeg; p.f.e_ref = 0.910; p.f.lambda_c = 0.122;
  p.f.xi = 0.71; p.f.A_d = 0.5; p.f.k_p = 0.001; p.f.n_p = 1; p.f.n_d = 1;
  return p;
}

inline PhaseTransitionParams<double> table3_collapse() {
  PhaseTransitionParams<double> p;
  p.c.rho_p = 2650; p.c.d = 1.25e-3; p.c.V_sd = 1.0 / 1.62; p.c.V_m = 0.4; p.c.eps_n = 0.6; p.c.mu_p = 0.2;
  p.f.K0 = 120; p.f.nu = 0.2; p.f.n = 0.5; p.f.phi_c = 19.8 * kDeg; p.f.e_ref = 0.977; p.f.lambda_c = 0.0596;
  p.f.xi = 0.365; p.f.A_d = 0.7; p.f.k_p = 0.0044; p.f.n_p = 2.4; p.f.n_d = 2.9;
  return p;
}

inline Mat3<double> isotropic(double p) { return -p * Mat3<double>::Identity(); }

// Velocity gradient of simple shear v = (rate * y, 0, 0).
inline Mat3<double> simple_shear(double rate) {
  Mat3<double> L = Mat3<double>::Zero();
  L(0, 1) = rate;
  return L;
}

}  // namespace granflow::test
