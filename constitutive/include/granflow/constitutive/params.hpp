// Parameter sets of the frictional and collisional parts (MODEL.md 7).
// Plain aggregates: copyable to the GPU as they are. Angles are stored in radians.
#pragma once

#include <cmath>

#include "config.hpp"

namespace granflow {

template <class S>
struct FrictionalParams {
  S K0 = 0;        // dimensionless reference bulk modulus, Eq. (13)
  S nu = 0;        // Poisson's ratio
  S n = 0;         // pressure exponent of the elasticity
  S phi_c = 0;     // critical-state friction angle [rad]
  S e_ref = 0;     // critical void ratio at p_f -> 0, Eq. (16)
  S lambda_c = 0;  // CSL rate constant, Eq. (16)
  S xi = 0;        // CSL curvature exponent, Eq. (16)
  S A_d = 0;       // stress-dilatancy constant, Eq. (15)
  S k_p = 0;       // plastic modulus constant, Eq. (14)
  S n_p = 0;       // interlocking exponent of the peak angle, Eq. (17)
  S n_d = 0;       // interlocking exponent of the phase-transformation angle, Eq. (18)
  S p_at = S(101.3e3);  // atmospheric pressure [Pa]

  // Numerics (MODEL.md 3.2, 3.6). p_min: moduli floor and start of the low-pressure regime.
  S p_min = S(1.013);      // ~1e-5 p_at
  // stol and ftol default to 1e-6 and 1e-9 for double; coarser types get what their epsilon
  // resolves (Tolerances<S> in config.hpp: 64 eps = 7.6e-6 for float).
  S stol = Tolerances<S>::kStol;  // relative local error tolerance of the substepping scheme
  S ftol = Tolerances<S>::kFtol;  // yield-surface tolerance on f = q/p - g M_p h (dimensionless)
  int max_substeps = 50;   // substep budget per update call (see StressIntegrator)
};

template <class S>
struct CollisionalParams {
  S rho_p = 0;  // particle density [kg/m^3]
  S d = 0;      // particle diameter [m]
  S V_sd = 0;   // solid fraction at which g0 diverges (random close packing), = 1/(1+e_sd)
  S V_m = 0;    // solid fraction where g0 starts to blend into the divergent branch
  S eps_n = 0;  // normal restitution coefficient
  S mu_p = 0;   // particle friction coefficient
  S vs_gap = S(1e-4);  // kinetic functions use V_s <= V_sd - vs_gap (MODEL.md 4.2, A9)

  // Options (docs/constitutive.md, "Options of the collisional part"). The defaults are
  // MODEL.md's model, computed with the same operations (bit for bit).
  // Where the effective restitution enters: a runtime choice; the models' template argument R
  // may also select DissipationOnly at compile time (either one selects it).
  RestitutionUse restitution = RestitutionUse::Everywhere;
  S k_mu = S(1.5);  // friction factor of Eq. (24): alpha = eps_n - k_mu mu_p exp(-3 mu_p)
  // Jamming fraction falling with particle friction: V_sd(mu_p) = V_sd_inf + (V_sd - V_sd_inf)
  // exp(-mu_p / mu_star); V_sd is then the frictionless value. Off: V_sd for every mu_p.
  bool jamming_friction = false;
  S V_sd_inf = 0;  // V_sd(mu_p -> infinity)
  S mu_star = 0;   // friction scale of the fall
  // Jenkins' correlation length in the dissipation: L/d = max(1, c_L sqrt(2J/(15(1-alpha^2)))
  // G_c^(1/3) d gammadot / sqrt(T)). 0: off (L = d).
  S corr_c = 0;
  // Dilute uniform-shear correction: the kinetic shear viscosity eta_k* times the factor
  // r = (1 - z)(1 - z/2), z = zeta0*/nu_eta*, that takes the Navier-Stokes steady simple shear to
  // the Grad-moment solution of uniform shear flow (Santos, Garzo & Dufty 2004). Off: r = 1.
  bool dilute_usf = false;
};

template <class S>
struct PhaseTransitionParams {
  FrictionalParams<S> f;
  CollisionalParams<S> c;
};

// Parameters in another floating-point type (the MPM's "fp32" precision runs the library in
// float with the double parameters of the scene). A coarser target type keeps stol and ftol at
// least at the tolerances it can resolve (Tolerances<T>); double to double is the identity.
template <class T, class S>
GF_HDI FrictionalParams<T> params_cast(const FrictionalParams<S>& p) {
  FrictionalParams<T> o;
  o.K0 = T(p.K0); o.nu = T(p.nu); o.n = T(p.n); o.phi_c = T(p.phi_c); o.e_ref = T(p.e_ref);
  o.lambda_c = T(p.lambda_c); o.xi = T(p.xi); o.A_d = T(p.A_d); o.k_p = T(p.k_p); o.n_p = T(p.n_p);
  o.n_d = T(p.n_d); o.p_at = T(p.p_at); o.p_min = T(p.p_min);
  o.stol = T(p.stol);
  o.ftol = T(p.ftol);
  if (Tolerances<T>::kCoarse) {
    if (o.stol < Tolerances<T>::kStol) o.stol = Tolerances<T>::kStol;
    if (o.ftol < Tolerances<T>::kFtol) o.ftol = Tolerances<T>::kFtol;
  }
  o.max_substeps = p.max_substeps;
  return o;
}

template <class T, class S>
GF_HDI CollisionalParams<T> params_cast(const CollisionalParams<S>& p) {
  CollisionalParams<T> o;
  o.rho_p = T(p.rho_p); o.d = T(p.d); o.V_sd = T(p.V_sd); o.V_m = T(p.V_m); o.eps_n = T(p.eps_n);
  o.mu_p = T(p.mu_p); o.vs_gap = T(p.vs_gap);
  o.restitution = p.restitution; o.k_mu = T(p.k_mu); o.jamming_friction = p.jamming_friction;
  o.V_sd_inf = T(p.V_sd_inf); o.mu_star = T(p.mu_star); o.corr_c = T(p.corr_c);
  o.dilute_usf = p.dilute_usf;
  return o;
}

template <class T, class S>
GF_HDI PhaseTransitionParams<T> params_cast(const PhaseTransitionParams<S>& p) {
  return {params_cast<T>(p.f), params_cast<T>(p.c)};
}

// Critical-state stress ratio M of a friction angle: 6 sin(phi) / (3 - sin(phi)).
template <class S>
GF_HDI S stress_ratio_of_angle(S sin_phi) {
  return S(6) * sin_phi / (S(3) - sin_phi);
}

// Effective restitution, Eq. (24) (Chialvo & Sundaresan 2013); k_mu = 1.5 there.
template <class S>
GF_HDI S effective_restitution(const CollisionalParams<S>& c) {
  return c.eps_n - c.k_mu * c.mu_p * std::exp(S(-3) * c.mu_p);
}

// Solid fraction at which g0 diverges, Eqs. (25)-(26): V_sd, or with jamming_friction the
// exponential fall with mu_p (after Chialvo, Sun & Sundaresan 2012; docs/constitutive.md).
template <class S>
GF_HDI S jamming_fraction(const CollisionalParams<S>& c) {
  if (!c.jamming_friction) return c.V_sd;
  return c.V_sd_inf + (c.V_sd - c.V_sd_inf) * std::exp(-c.mu_p / c.mu_star);
}

// Upper bound of void ratio in Eq. (13): the factor (2.97 - e) must stay positive.
inline constexpr double kVoidRatioMax = 2.97;

// Void ratio after a volumetric strain ev (tension +): (1 + e) = (1 + e0) exp(ev), exact (MODEL.md
// 3.7). In double as (1 + e0) exp(ev) - 1. In float the increments of an MPM step (|ev| ~ 1e-7 to
// 1e-4) are below or near float's resolution of exp(ev) around 1, which rounds them by up to 15 %,
// the same way every step; e0 + (1 + e0) expm1(ev) resolves them.
template <class S>
GF_HDI S void_ratio_after(S e0, S ev) {
  if constexpr (Tolerances<S>::kCoarse) {
    return e0 + (S(1) + e0) * std::expm1(ev);
  } else {
    return (S(1) + e0) * std::exp(ev) - S(1);
  }
}

}  // namespace granflow
