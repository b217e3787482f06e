// Collisional part: dense kinetic theory after Garzo & Dufty (1999) as used by the source
// (MODEL.md 4-5). The granular temperature is carried as s = sqrt(T): its balance is a
// Riccati equation ds/dt = A - B s - C s^2 whose right-hand side is Lipschitz at s = 0
// (dT/dt ~ sqrt(T) is not), so the tiny seed T0 = 1e-15 is harmless.
#pragma once

#include <cmath>

#include "config.hpp"
#include "params.hpp"
#include "state_check.hpp"
#include "tensor.hpp"

namespace granflow {

inline constexpr double kSqrtPi = 1.7724538509055160273;
inline constexpr double kPi = 3.14159265358979323846;

// g0 of Eqs. (25)-(26): Carnahan-Starling below V_m, blended into 2/(V_sd - V_s).
template <class S>
GF_HDI S radial_distribution(S Vs, S V_m, S V_sd) {
  const S one_m = S(1) - Vs;
  const S g_cs = (S(2) - Vs) / (S(2) * one_m * one_m * one_m);
  if (Vs < V_m) return g_cs;
  const S t = (Vs - V_m) / (V_sd - V_m);
  const S f = S(1) - t * t;
  return f * g_cs + (S(1) - f) * S(2) / (V_sd - Vs);
}

// Auxiliary functions of Appendix A/B at one (V_s, alpha).
template <class S>
struct KineticFunctions {
  S g0, Gc, c_star, zeta0_star, nu_eta_star, eta_k_star, kappa_star, eta_star, F, J, Q, p_star;
};

template <class S>
GF_HDI KineticFunctions<S> kinetic_functions(S Vs, S g0, S a) {
  KineticFunctions<S> k;
  k.g0 = g0;
  k.Gc = Vs * g0;  // Eq. (23) corrected: G = V_s g0, dimensionless
  const S a2 = a * a;
  k.c_star = S(32) * (S(1) - a) * (S(1) - S(2) * a2) / (S(81) - S(17) * a + S(30) * a2 * (S(1) - a));  // A9
  k.zeta0_star = S(5) / S(12) * g0 * (S(1) - a2) * (S(1) + S(3) / S(32) * k.c_star);                   // A7
  k.nu_eta_star = g0 * (S(1) - S(0.25) * (S(1) - a) * (S(1) - a)) * (S(1) - k.c_star / S(64));         // A8
  k.eta_k_star = (S(1) - S(0.4) * (S(1) + a) * (S(1) - S(3) * a) * k.Gc) /
                 (k.nu_eta_star - S(0.5) * k.zeta0_star);                                                 // A6
  k.kappa_star = S(128) / (S(5) * S(kPi)) * Vs * k.Gc * (S(1) + a) * (S(1) - k.c_star / S(32));         // A5 corr.
  k.eta_star = k.eta_k_star * (S(1) + S(0.8) * k.Gc * (S(1) + a)) + S(0.6) * k.kappa_star;             // A4
  k.F = S(1) / (S(4) * k.Gc) + S(0.5) * (S(1) + a);                                                     // A1
  const S one_e = S(1) / Vs;                                                                            // 1 + e
  k.J = S(25) * S(kPi) * one_e * k.eta_star / (S(768) * k.Gc);                                         // A2
  k.Q = S(5) * S(kPi) * one_e * k.kappa_star / (S(128) * k.Gc);                                        // A3
  k.p_star = S(1) + S(2) * (S(1) + a) * k.Gc;                                                           // = 4 Gc F
  return k;
}

// First-order cooling coefficient zeta_U of Eqs. (B11)-(B14) (MFIX form of lambda, MODEL.md 5.1).
template <class S>
GF_HDI S cooling_coefficient_zetaU(const KineticFunctions<S>& k, S a) {
  const S a2 = a * a, a3 = a2 * a, cs = k.c_star;
  const S lambda_gd = S(0.375) * (S(1) + a) *
                      ((S(1) - a) * (S(5) * a2 + S(4) * a - S(1)) +
                       cs / S(12) * (S(159) * a + S(3) * a2 - S(19) * a - S(15) * a3));  // B14
  const S nu_gamma = (S(1) + a) / S(48) * k.g0 *
                     (S(128) - S(96) * a + S(15) * a2 - S(15) * a3 +
                      cs / S(64) * (S(15) * a3 - S(15) * a2 + S(498) * a - S(434)));      // B13
  const S diss = k.g0 * (S(1) - a2);
  const S C_D = (S(4) / S(15) * lambda_gd * k.Gc + (k.p_star - S(1)) * (S(2) / S(3) - a) * cs) /
                (S(0.5) * k.zeta0_star + nu_gamma + S(5) / S(64) * cs * (S(1) + S(3) / S(64) * cs) * diss);  // B12
  return -(S(1) - a) * (k.p_star - S(1)) + S(5) / S(32) * (S(1) - a2) * (S(1) + S(3) / S(64) * cs) * k.g0 * C_D;  // B11
}

// Dilute uniform shear flow, Grad's moment method (Santos, Garzo & Dufty 2004): with the
// collision moments -nu (beta Pi_ij + zeta* p delta_ij), the steady state has
// a*^2 = (3/2) zeta* beta^2 / (beta - zeta*), the Navier-Stokes one (3/2) zeta* (beta - zeta*/2).
// T scales as 1/a*^2 at a given shear rate: T_Grad / T_NS = (1 - z)(1 - z/2), z = zeta*/beta, and
// the Navier-Stokes balance gives this T when eta_k* is multiplied by the same factor.
template <class S>
GF_HDI S uniform_shear_viscosity_factor(S z) {
  const S r = (S(1) - z) * (S(1) - S(0.5) * z);
  return r > S(0) ? r : S(0);
}

// Everything the collisional stress and the temperature balance need at one solid fraction,
// in the dimensionless groups of MODEL.md 5.2:
//   eta_c = rho_p d K_eta s,  kappa_c = rho_p d K_kappa s,  Gamma_0 = rho_p K_Gamma s^3 / d.
template <class S>
struct KineticCoefficients {
  S Vs;       // solid fraction used (clamped below V_sd)
  S g0, Gc;
  S p_star;   // p_c = rho_p V_s p* T
  S K_eta, K_kappa, K_Gamma, zeta_U;
  S lambda_L;  // correlation length L/d = max(1, lambda_L d gammadot / s); 0: option off (L = d)
  bool clamped;
};

template <RestitutionUse R = RestitutionUse::Everywhere, class S>
GF_HDI KineticCoefficients<S> kinetic_coefficients(const CollisionalParams<S>& c, S Vs_in) {
  KineticCoefficients<S> kc;
  const S V_sd = jamming_fraction(c);
  const S Vs_max = V_sd - c.vs_gap;
  kc.clamped = Vs_in > Vs_max;
  const S Vs = kc.clamped ? Vs_max : (Vs_in > S(0) ? Vs_in : S(0));
  kc.Vs = Vs;
  const bool diss_only = R == RestitutionUse::DissipationOnly || c.restitution == RestitutionUse::DissipationOnly;
  const S a_diss = effective_restitution(c);
  const S a_tr = diss_only ? c.eps_n : a_diss;
  const S g0 = radial_distribution(Vs, c.V_m, V_sd);
  const KineticFunctions<S> kt = kinetic_functions(Vs, g0, a_tr);
  kc.g0 = g0;
  kc.Gc = kt.Gc;
  kc.p_star = kt.p_star;
  S zeta0 = kt.zeta0_star;
  kc.K_kappa = S(4) / (S(3) * S(kSqrtPi)) * Vs * kt.Gc * kt.Q;
  if (!diss_only) {
    kc.K_Gamma = S(144) / (S(5) * S(kSqrtPi)) * Vs * Vs * kt.zeta0_star;
    kc.zeta_U = cooling_coefficient_zetaU(kt, a_diss);
  } else {
    const KineticFunctions<S> kd = kinetic_functions(Vs, g0, a_diss);
    zeta0 = kd.zeta0_star;
    kc.K_Gamma = S(144) / (S(5) * S(kSqrtPi)) * Vs * Vs * kd.zeta0_star;
    kc.zeta_U = cooling_coefficient_zetaU(kd, a_diss);
  }
  S J = kt.J;
  if (c.dilute_usf) {  // eta_k* -> r eta_k* in A4, then A2 (uniform_shear_viscosity_factor)
    const S eta_star = kt.eta_k_star * uniform_shear_viscosity_factor(zeta0 / kt.nu_eta_star) *
                           (S(1) + S(0.8) * kt.Gc * (S(1) + a_tr)) +
                       S(0.6) * kt.kappa_star;
    J = S(25) * S(kPi) * eta_star / (S(768) * kt.Gc * Vs);
  }
  kc.K_eta = S(8) / (S(5) * S(kSqrtPi)) * Vs * kt.Gc * J;
  // Jenkins (2006, 2007): L/d = max(1, c_L sqrt(2J/(15(1 - alpha^2))) G_c^(1/3) d gammadot / sqrt(T)).
  const S one_m_a2 = S(1) - a_diss * a_diss;
  kc.lambda_L = c.corr_c > S(0) && one_m_a2 > S(0)
                    ? c.corr_c * std::sqrt(S(2) * J / (S(15) * one_m_a2)) * std::cbrt(kt.Gc)
                    : S(0);
  return kc;
}

// L/d of the correlation-length option at shear rate gammadot = sqrt(2 D':D') and s = sqrt(T),
// capped at 1e6 (s -> 0 under shear: no dissipation, s grows as A t); 1 when the option is off.
template <class S>
GF_HDI S correlation_length(const KineticCoefficients<S>& kc, S d, S shear_rate, S s) {
  const S x = kc.lambda_L * d * shear_rate;
  if (!(x > s)) return S(1);
  return x < S(1e6) * s ? x / s : S(1e6);
}

// Pressure and viscosities, Eqs. (20)-(22).
template <class S>
struct CollisionalTransport {
  S p, eta, kappa;
};

template <class S>
GF_HDI CollisionalTransport<S> collisional_transport(const CollisionalParams<S>& c, const KineticCoefficients<S>& kc,
                                                     S s) {
  return {c.rho_p * kc.Vs * kc.p_star * s * s, c.rho_p * c.d * kc.K_eta * s, c.rho_p * c.d * kc.K_kappa * s};
}

// Eq. (19) restated tension-positive: sigma_c = -p_c I + 2 eta_c D' + kappa_c tr(D) I.
template <class S>
GF_HDI Mat3<S> collisional_stress(const CollisionalTransport<S>& t, const Mat3In<S>& D) {
  return (-t.p + t.kappa * trace(D)) * identity3<S>() + S(2) * t.eta * dev(D);
}

// Coefficients of ds/dt = A - B s - C s^2 (MODEL.md 5.2), frozen over a step.
template <class S>
struct RiccatiCoefficients {
  S A, B, C;
};

// s: the sqrt(T) at which the correlation length (if on) is evaluated: the current value for an
// ODE solver's right-hand side, the start of the step for the frozen-coefficient update.
template <class S>
GF_HDI RiccatiCoefficients<S> temperature_balance(const CollisionalParams<S>& c, const KineticCoefficients<S>& kc,
                                                  const Mat3In<S>& D, S s) {
  const S trD = trace(D);
  const Mat3<S> Dd = dev(D);
  const S DdDd = ddot(Dd, Dd);
  const S A = c.d * (S(2) * kc.K_eta * DdDd + kc.K_kappa * trD * trD) / (S(3) * kc.Vs);
  const S B = S(0.5) * trD * (S(2) / S(3) * kc.p_star + kc.zeta_U);
  S C = kc.K_Gamma / (S(3) * kc.Vs * c.d);
  if (kc.lambda_L > S(0)) C /= correlation_length(kc, c.d, std::sqrt(S(2) * DdDd), s);
  return {A, B, C};
}

template <class S>
GF_HDI S sqrt_temperature_rate(const RiccatiCoefficients<S>& r, S s) {
  return r.A - r.B * s - r.C * s * s;
}

// phi(x) = (1 - exp(-x)) / x, continuous at 0.
template <class S>
GF_HDI S one_minus_exp_over_x(S x) {
  return std::fabs(x) < S(1e-8) ? S(1) - S(0.5) * x : -std::expm1(-x) / x;
}

// Exact solution of ds/dt = A - B s - C s^2 with frozen coefficients over dt (MODEL.md 5.2, A10).
// With w = s - s+ (s+ the non-negative root) the Bernoulli equation gives
//   s(dt) = s+ + w0 E / (1 + w0 C dt phi(R dt)),  E = exp(-R dt),  R = sqrt(B^2 + 4AC).
// Because s+ <= s+ - s- the denominator stays >= E > 0: s is finite and >= 0 for every dt >= 0,
// which is why this update is unconditionally stable however stiff the balance (tiny T, huge g0).
template <class S>
GF_HDI S advance_sqrt_temperature(const RiccatiCoefficients<S>& r, S s0, S dt) {
  const S A = r.A, B = r.B, C = r.C;
  if (!(C > S(0))) {  // alpha = 1: no dissipation, linear equation ds/dt = A - B s
    const S s = s0 * std::exp(-B * dt) + A * dt * one_minus_exp_over_x(B * dt);
    return s > S(0) ? s : S(0);
  }
  const S R = std::sqrt(B * B + S(4) * A * C);
  // stable root, free of cancellation whatever the sign of B
  const S s_plus = B >= S(0) ? (R > S(0) ? S(2) * A / (B + R) : S(0)) : (R - B) / (S(2) * C);
  const S w0 = s0 - s_plus;
  const S E = std::exp(-R * dt);
  if constexpr (Tolerances<S>::kCoarse) {
    // The same solution without the cancellation of s+ against w0 E / (...) when s << s+ (a
    // point starting to shear from the seed temperature; in float 1e-3 relative error at
    // s ~ 1e-6 m/s): with 1 - E = R dt phi and R - C s+ = -C s-, s+ s- = -A/C,
    //   s = (A dt phi + s0 (E + s+ C dt phi)) / (1 + w0 C dt phi), every numerator term >= 0.
    const S cdp = C * dt * one_minus_exp_over_x(R * dt);
    const S s = (A * (dt * one_minus_exp_over_x(R * dt)) + s0 * (E + s_plus * cdp)) / (S(1) + w0 * cdp);
    return s > S(0) ? s : S(0);
  } else {
    const S s = s_plus + w0 * E / (S(1) + w0 * C * dt * one_minus_exp_over_x(R * dt));
    return s > S(0) ? s : S(0);
  }
}

// Steady simple shear (MODEL.md 5.3): Bagnold-scaled T, p_c, tau_c and mu_c.
template <class S>
struct SteadyShear {
  S T, p, tau, mu;
};

// With the correlation length, L/d = lambda_L d gammadot / sqrt(T) and T = (L/d)(K_eta/K_Gamma) d^2
// gammadot^2 give L/d = max(1, lambda_L^(2/3) (K_Gamma/K_eta)^(1/3)).
template <class S>
GF_HDI SteadyShear<S> steady_simple_shear(const CollisionalParams<S>& c, const KineticCoefficients<S>& kc,
                                          S shear_rate) {
  const S d2g2 = c.d * c.d * shear_rate * shear_rate;
  if (kc.lambda_L > S(0)) {
    const S l = std::cbrt(kc.lambda_L * kc.lambda_L * kc.K_Gamma / kc.K_eta);
    const S ell = l > S(1) ? l : S(1);
    const S ratio = ell * kc.K_eta / kc.K_Gamma;
    return {ratio * d2g2, c.rho_p * kc.Vs * kc.p_star * ratio * d2g2, c.rho_p * kc.K_eta * std::sqrt(ratio) * d2g2,
            std::sqrt(kc.K_eta * kc.K_Gamma / ell) / (kc.Vs * kc.p_star)};
  }
  const S ratio = kc.K_eta / kc.K_Gamma;
  return {ratio * d2g2, c.rho_p * kc.Vs * kc.p_star * ratio * d2g2,
          c.rho_p * kc.K_eta * std::sqrt(ratio) * d2g2, std::sqrt(kc.K_eta * kc.K_Gamma) / (kc.Vs * kc.p_star)};
}

// ---- Collisional-only model ------------------------------------------------------------

template <class S>
struct CollisionalState {
  S e = 0;  // void ratio
  S s = 0;  // sqrt of the granular temperature [m/s]
};

// One step: void ratio (exact volumetric update), then s over dt with frozen coefficients at
// the new V_s. Returns the collisional stress at the end of the step.
template <RestitutionUse R = RestitutionUse::Everywhere, class S>
GF_HDI UpdateInfo collisional_update(const CollisionalParams<S>& c, CollisionalState<S>& st, const Mat3In<S>& grad_v,
                                     S dt, Mat3<S>& stress) {
  UpdateInfo inf;
  inf.substeps = 1;
  const Mat3<S> D = sym(grad_v);
  const S e1 = void_ratio_after(st.e, trace(D) * dt);
  if (!(e1 > S(0)) || !std::isfinite(e1) || !admissible_sqrt_temperature(st.s)) {
    inf.flags |= info::kInadmissible;
    return inf;
  }
  const KineticCoefficients<S> kc = kinetic_coefficients<R>(c, S(1) / (S(1) + e1));
  if (kc.clamped) inf.flags |= info::kVsClamped;
  const S s1 = advance_sqrt_temperature(temperature_balance(c, kc, D, st.s), st.s, dt);
  const Mat3<S> sig = collisional_stress(collisional_transport(c, kc, s1), D);
  if (!std::isfinite(s1) || !all_finite(sig)) {
    inf.flags |= info::kNonFinite;
    return inf;
  }
  st.e = e1;
  st.s = s1;
  stress = sig;
  return inf;
}

}  // namespace granflow
