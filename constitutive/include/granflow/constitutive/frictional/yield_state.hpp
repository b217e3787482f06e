// Yield function with hardening, Eq. (14), and non-associated flow rule, Eq. (15), at one
// state (MODEL.md 3.4-3.5), with the derivatives the consistency condition needs.
#pragma once

#include <cmath>

#include "../config.hpp"
#include "../params.hpp"
#include "../tensor.hpp"
#include "critical_state.hpp"
#include "elasticity.hpp"
#include "lode_shape.hpp"

namespace granflow {

// ---- Stress-state kinematics shared by yield function and flow rule --------------------

template <class S>
struct StressInvariants {
  S p;            // mean pressure (compression +)
  S q;            // sqrt(3 J2)
  S J2;
  S x;            // sin(3 theta)
  Mat3<S> s;      // deviator
  Mat3<S> s_hat;  // unit deviatoric direction, q(s_hat) = 1
};

// `direction_hint` supplies the deviatoric direction when q vanishes (the cone vertex:
// MODEL.md 3.6 takes it from dev(D) for the first increment).
template <class S>
GF_HDI StressInvariants<S> stress_invariants(const Mat3<S>& sigma, const Mat3In<S>& direction_hint) {
  StressInvariants<S> inv;
  inv.p = mean_pressure(sigma);
  inv.s = dev(sigma);
  inv.J2 = S(0.5) * ddot(inv.s, inv.s);
  inv.q = std::sqrt(S(3) * inv.J2);
  const S scale = inv.p > S(0) ? inv.p : S(1);
  if (inv.q > Tolerances<S>::kIsotropic * scale) {
    inv.x = sin3theta(inv.s, inv.J2);
    inv.s_hat = inv.s / inv.q;
  } else {
    const Mat3<S> h = dev(direction_hint);
    const S qh = std::sqrt(S(1.5) * ddot(h, h));
    inv.s_hat = qh > S(0) ? Mat3<S>(h / qh) : Mat3<S>(Mat3<S>::Zero());
    inv.x = S(0);
    inv.q = S(0);
  }
  return inv;
}

// Everything of the yield function (Eq. 14, corrected: M_p) and the flow rule (Eq. 15,
// non-associated) at one state, with the derivatives the consistency condition needs.
template <class S>
struct YieldState {
  ElasticModuli<S> C;
  S r;        // q / p
  S e_c;      // critical void ratio
  S Gm;       // g(theta; phi_p) M_p : the ratio the cone hardens towards
  S h, dh;    // h = eps/(k_p + eps), dh/deps
  S f;        // yield function r - Gm h
  S Dg;       // dilatancy A_d (g(theta; phi_pt) M_pt - r)
  S dGm_de;   // partial derivative of Gm in e at fixed p
  Mat3<S> n;  // df/dsigma (includes the p-dependence of e_c and the Lode angle)
  Mat3<S> m;  // plastic flow direction: deps^p = dLambda m
};

template <LodeShape L, class S>
GF_HDI YieldState<S> yield_state(const FrictionalParams<S>& mp, const Mat3In<S>& sigma, S eps_pd, S e,
                                 const Mat3In<S>& direction_hint) {
  YieldState<S> y;
  const StressInvariants<S> inv = stress_invariants(sigma, direction_hint);
  const S pe = inv.p > mp.p_min ? inv.p : mp.p_min;
  y.C = elastic_moduli(mp, inv.p, e);
  const S inv_pe = S(1) / pe;
  y.r = inv.q * inv_pe;

  // Eqs. (16)-(18): state-dependent peak and phase-transformation angles. One power of p and
  // the logarithm of e_c / e serve e_c, its p-derivative and both angles.
  const S xpow = std::pow(pe / mp.p_at, mp.xi);
  y.e_c = mp.e_ref * std::exp(-mp.lambda_c * xpow);
  const S dec_dp = inv.p > mp.p_min ? -y.e_c * mp.lambda_c * mp.xi * xpow * inv_pe : S(0);
  const S tan_c = std::tan(mp.phi_c);
  const S log_ratio = std::log(mp.e_ref / e) - mp.lambda_c * xpow;
  const S tan_p = std::exp(mp.n_p * log_ratio) * tan_c;
  const S tan_pt = std::exp(-mp.n_d * log_ratio) * tan_c;
  const ConeRatio<S> cp = cone_ratio<L>(inv.x, tan_p), cpt = cone_ratio<L>(inv.x, tan_pt);

  y.Gm = cp.gM;
  const S inv_kp_eps = S(1) / (mp.k_p + eps_pd);
  y.h = eps_pd * inv_kp_eps;
  y.dh = mp.k_p * inv_kp_eps * inv_kp_eps;
  y.f = y.r - y.Gm * y.h;
  y.Dg = mp.A_d * (cpt.gM - y.r);

  // The chain of Gm through tan(phi_p)(e, e_c(p)).
  const S dtan_dec = mp.n_p * tan_p / y.e_c;
  const S dGm_dp = cp.dgM_dtan * dtan_dec * dec_dp;
  y.dGm_de = cp.dgM_dtan * (-mp.n_p * tan_p / e);

  // n = d r / d sigma - h d Gm / d sigma;  d p / d sigma = -I/3, d q / d sigma = 3/2 s_hat.
  const Mat3<S> I = identity3<S>();
  const Mat3<S> dr = (S(1.5) * inv_pe) * inv.s_hat + (inv.p > mp.p_min ? y.r * inv_pe / S(3) : S(0)) * I;
  const Mat3<S> dGm = cp.dgM_dx * dsin3theta_dsigma(inv.s, inv.J2) - (dGm_dp / S(3)) * I;
  y.n = dr - y.h * dGm;
  // Flow rule (15): d eps^p = dLambda [-(1/3) Dg I + 3/2 s_hat] (radial deviatoric flow, A3).
  y.m = (-y.Dg / S(3)) * I + S(1.5) * inv.s_hat;
  return y;
}

// Yield function value alone.
template <LodeShape L, class S>
GF_HDI S yield_function(const FrictionalParams<S>& mp, const Mat3In<S>& sigma, S eps_pd, S e) {
  return yield_state<L>(mp, sigma, eps_pd, e, Mat3<S>::Zero()).f;
}

// Initial hardening variable putting an initial stress on f = 0 (MODEL.md 3.4, A4):
// eps_pd0 = k_p r0 / (g M_p - r0). Returns a negative value when r0 >= g M_p (inadmissible).
template <LodeShape L, class S>
GF_HDI S initial_plastic_strain(const FrictionalParams<S>& mp, const Mat3In<S>& sigma, S e) {
  const YieldState<S> y = yield_state<L>(mp, sigma, S(0), e, Mat3<S>::Zero());
  if (!(y.r < y.Gm)) return S(-1);
  return mp.k_p * y.r / (y.Gm - y.r);
}

}  // namespace granflow
