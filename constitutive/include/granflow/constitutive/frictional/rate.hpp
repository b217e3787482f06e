// Rate law: consistency condition and plastic multiplier at a frozen state (MODEL.md 3.6).
#pragma once

#include "../config.hpp"
#include "../params.hpp"
#include "../tensor.hpp"
#include "elasticity.hpp"
#include "yield_state.hpp"

namespace granflow {

template <class S>
struct FrictionalRate {
  Mat3<S> dsigma;  // stress increment (or rate)
  S deps_pd;       // plastic multiplier increment
  bool plastic;
};

// Stress response to a strain increment deps (or a rate D) at a frozen state, with the full
// consistency condition: df = n:dsigma - Gm h' dLambda - h dGm/de de = 0 (MODEL.md 3.6, rate
// form), de = (1 + e) tr(deps). Plastic when on the surface (f >= -ftol_load) and loading.
// `force_plastic` skips the surface test and takes dLambda = max(0, ...): the second stage of
// a plastic substep keeps the regime of the first, whose predictor may end slightly inside the
// surface (switching to elastic there would make the error estimate O(dT), not O(dT^2)).
template <LodeShape L, class S>
GF_HDI FrictionalRate<S> frictional_rate(const FrictionalParams<S>& mp, const Mat3In<S>& sigma, S eps_pd,
                                         S e, const Mat3In<S>& deps, S ftol_load, bool force_plastic = false) {
  const YieldState<S> y = yield_state<L>(mp, sigma, eps_pd, e, deps);
  const Mat3<S> dsig_e = apply_elastic(y.C, deps);
  FrictionalRate<S> out{dsig_e, S(0), false};
  if (!force_plastic && y.f < -ftol_load) return out;
  const S de = (S(1) + e) * trace(deps);
  const S numer = ddot(y.n, dsig_e) - y.h * y.dGm_de * de;
  if (!(numer > S(0))) {
    out.plastic = force_plastic;
    return out;
  }
  const Mat3<S> Cm = apply_elastic(y.C, y.m);
  const S denom = ddot(y.n, Cm) + y.Gm * y.dh;
  if (!(denom > S(0))) return out;  // no admissible plastic solution: elastic predictor kept
  const S dL = numer / denom;
  out.dsigma = dsig_e - dL * Cm;
  out.deps_pd = dL;
  out.plastic = true;
  return out;
}

}  // namespace granflow
