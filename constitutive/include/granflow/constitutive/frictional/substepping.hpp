// Explicit integration of the rate law over a strain increment: modified-Euler substepping
// with local error control and drift correction (Sloan et al. 2001; MODEL.md 3.6).
#pragma once

#include <cmath>

#include "../config.hpp"
#include "../params.hpp"
#include "../state_check.hpp"
#include "../tensor.hpp"
#include "elasticity.hpp"
#include "rate.hpp"
#include "return_map.hpp"
#include "state.hpp"
#include "yield_state.hpp"

namespace granflow {

namespace detail {

template <class S>
GF_HDI S stress_norm(const Mat3<S>& a) {
  return std::sqrt(ddot(a, a));
}

// Consistent drift correction back to f = 0 (Sloan et al. 2001, Sect. 4): a few Newton steps
// along C^e m at fixed e; falls back to a step along n when it diverges.
template <LodeShape L, class S>
GF_HDI void correct_drift(const FrictionalParams<S>& mp, Mat3<S>& sigma, S& eps_pd, S e,
                          const Mat3In<S>& hint) {
  for (int it = 0; it < 6; ++it) {
    const YieldState<S> y = yield_state<L>(mp, sigma, eps_pd, e, hint);
    if (!(std::fabs(y.f) > mp.ftol)) return;
    const Mat3<S> Cm = apply_elastic(y.C, y.m);
    const S denom = ddot(y.n, Cm) + y.Gm * y.dh;
    Mat3<S> s_new;
    S k_new = eps_pd;
    if (denom > S(0)) {
      const S dL = y.f / denom;
      s_new = sigma - dL * Cm;
      k_new = eps_pd + dL;
    } else {
      s_new = sigma - (y.f / ddot(y.n, y.n)) * y.n;
    }
    const S f_new = yield_state<L>(mp, s_new, k_new > S(0) ? k_new : S(0), e, hint).f;
    if (!(std::fabs(f_new) < std::fabs(y.f))) {
      s_new = sigma - (y.f / ddot(y.n, y.n)) * y.n;  // normal correction
      k_new = eps_pd;
    }
    sigma = s_new;
    eps_pd = k_new > S(0) ? k_new : S(0);
  }
}

}  // namespace detail

// Integrates the rate law over the strain increment deps (tension-positive, no spin):
// 1. elastic predictor; if it stays inside the surface, done.
// 2. otherwise find the fraction alpha at which the elastic path meets f = 0 (regula falsi),
// 3. substep the rest with modified Euler, local error control (stol) and drift correction.
// Near zero pressure (free surface, liquefied material) the moduli and e_c are evaluated at
// p_min, which also rounds the cone apex (q <= g M_p h p_min below p_min); whenever the mean
// stress reaches zero the tension cut-off sets sigma_f = 0: a cohesionless skeleton carries
// no tension (MODEL.md 3.2, A5). A zero-stress state restarts elastically from zero.
// When the substep budget (max_substeps) is spent, the rest of the increment is completed by
// the implicit return map (ImplicitCompletion, the Hybrid integrator) or by eight uncontrolled
// substeps; both raise kSubstepLimit.
template <LodeShape L, bool ImplicitCompletion = true, class S>
GF_HDI UpdateInfo frictional_increment(const FrictionalParams<S>& mp, FrictionalState<S>& st,
                                       const Mat3In<S>& deps) {
  UpdateInfo inf;
  const S e0 = st.e;
  const S e1 = void_ratio_after(e0, trace(deps));  // exact volumetric update (3.7)
  if (frictional_state_fault(st.sigma, st.eps_pd, e0) != StateFault::None || !admissible_void_ratio(e1)) {
    inf.flags |= info::kInadmissible;
    return inf;
  }
  Mat3<S> sigma = st.sigma;
  S eps = st.eps_pd;
  const S p0 = mean_pressure(sigma);
  if (!(p0 > S(0))) sigma = Mat3<S>::Zero();  // a cut-off state carries no stress

  if (!(p0 > mp.p_min)) inf.flags |= info::kPressureFloor;

  // 1. elastic predictor
  const S f0 = yield_state<L>(mp, sigma, eps, e0, deps).f;
  const Mat3<S> trial = detail::elastic_predictor(mp, sigma, e0, e1, deps);
  if (!(mean_pressure(trial) > S(0))) {  // the skeleton opens: tension cut-off (MODEL.md 3.2, A5)
    st.sigma = Mat3<S>::Zero();
    st.eps_pd = eps;
    st.e = e1;
    inf.flags |= info::kTensionCutoff;
    inf.substeps = 1;
    return inf;
  }
  const S f1 = yield_state<L>(mp, trial, eps, e1, deps).f;
  S alpha = S(0);
  if (!(f1 > mp.ftol)) {
    sigma = trial;
    inf.substeps = 1;
  } else {
    // 2. elastic part of a crossing increment
    if (f0 < -mp.ftol) {
      S a0 = S(0), a1 = S(1), fa0 = f0, fa1 = f1;
      for (int it = 0; it < 40; ++it) {
        alpha = a1 - fa1 * (a1 - a0) / (fa1 - fa0);
        const S ea = void_ratio_after(e0, alpha * trace(deps));
        const S fa = yield_state<L>(mp, detail::elastic_predictor<S>(mp, sigma, e0, ea, alpha * deps), eps,
                                    ea, deps)
                         .f;
        if (std::fabs(fa) <= mp.ftol) break;
        if ((fa < S(0)) == (fa0 < S(0))) {
          a0 = alpha; fa0 = fa; fa1 *= S(0.5);  // Illinois modification
        } else {
          a1 = alpha; fa1 = fa; fa0 *= S(0.5);
        }
      }
      const S ea = void_ratio_after(e0, alpha * trace(deps));
      sigma = detail::elastic_predictor<S>(mp, sigma, e0, ea, alpha * deps);
    }
    // 3. substepping of the plastic part
    const S ftol_load = S(100) * mp.ftol + S(1e-6);
    const Mat3<S> d_rest = (S(1) - alpha) * deps;
    S T = S(0), dT = S(1);
    S e = void_ratio_after(e0, alpha * trace(deps));
    const S trd = trace(d_rest);
    int n = 0;
    bool budget_spent = false;
    while (T < S(1)) {
      if (++n > mp.max_substeps && !budget_spent) {
        inf.flags |= info::kSubstepLimit;
        if constexpr (ImplicitCompletion) {
          FrictionalState<S> rest{sigma, eps, e};
          const UpdateInfo ri = frictional_return_map<L>(mp, rest, Mat3<S>((S(1) - T) * d_rest));
          inf.flags |= ri.flags;
          inf.halvings += ri.halvings;
          if (!ri.ok()) return inf;
          sigma = rest.sigma;
          eps = rest.eps_pd;
          n += ri.substeps;
          break;
        }
        // Bounded work per call: finish in 8 equal steps without error control.
        budget_spent = true;
        dT = (S(1) - T) / S(8);
      }
      const Mat3<S> dd = dT * d_rest;
      const S e_mid = void_ratio_after(e, dT * trd);
      const FrictionalRate<S> r1 = frictional_rate<L>(mp, sigma, eps, e, dd, ftol_load);
      const FrictionalRate<S> r2 =
          frictional_rate<L>(mp, Mat3<S>(sigma + r1.dsigma), eps + r1.deps_pd, e_mid, dd, ftol_load, r1.plastic);
      const Mat3<S> s_new = sigma + S(0.5) * (r1.dsigma + r2.dsigma);
      const S k_new = eps + S(0.5) * (r1.deps_pd + r2.deps_pd);
      const S scale = detail::stress_norm(s_new) + mp.p_min;
      S R = S(0.5) * detail::stress_norm<S>(r2.dsigma - r1.dsigma) / scale;
      const S Rk = S(0.5) * std::fabs(r2.deps_pd - r1.deps_pd) / (k_new + mp.k_p);
      R = R > Rk ? R : Rk;
      if (!(R == R)) {  // NaN
        inf.flags |= info::kNonFinite;
        return inf;
      }
      const S fac = R > S(0) ? S(0.9) * std::sqrt(mp.stol / R) : S(2);
      if (R > mp.stol && !budget_spent && dT > Tolerances<S>::kMinSubstep) {
        dT *= fac < S(0.1) ? S(0.1) : fac;
        continue;
      }
      sigma = s_new;
      eps = k_new;
      e = e_mid;
      if (mean_pressure(sigma) <= S(0)) {  // liquefied within the increment: tension cut-off
        sigma = Mat3<S>::Zero();
        inf.flags |= info::kTensionCutoff;
        break;
      }
      if (r1.plastic || r2.plastic) detail::correct_drift<L>(mp, sigma, eps, e, deps);
      T += dT;
      if (!budget_spent) dT *= fac > S(2) ? S(2) : (fac < S(0.1) ? S(0.1) : fac);
      if (dT > S(1) - T) dT = S(1) - T;
    }
    inf.substeps = n;
  }
  if (!all_finite(sigma) || !std::isfinite(eps)) {
    inf.flags |= info::kNonFinite;
    return inf;
  }
  st.sigma = sigma;
  st.eps_pd = eps;
  st.e = e1;
  return inf;
}

}  // namespace granflow
