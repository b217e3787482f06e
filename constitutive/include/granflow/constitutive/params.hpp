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
  S stol = S(1e-6);        // relative local error tolerance of the substepping scheme
  S ftol = S(1e-9);        // yield-surface tolerance on f = q/p - g M_p h (dimensionless)
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
};

template <class S>
struct PhaseTransitionParams {
  FrictionalParams<S> f;
  CollisionalParams<S> c;
};

// Critical-state stress ratio M of a friction angle: 6 sin(phi) / (3 - sin(phi)).
template <class S>
GF_HDI S stress_ratio_of_angle(S sin_phi) {
  return S(6) * sin_phi / (S(3) - sin_phi);
}

// Effective restitution, Eq. (24) (Chialvo & Sundaresan 2013).
template <class S>
GF_HDI S effective_restitution(const CollisionalParams<S>& c) {
  return c.eps_n - S(1.5) * c.mu_p * std::exp(S(-3) * c.mu_p);
}

// Upper bound of void ratio in Eq. (13): the factor (2.97 - e) must stay positive.
inline constexpr double kVoidRatioMax = 2.97;

}  // namespace granflow
