// Implicit return map of the frictional part (MODEL.md 3.6, A7): the default integrator of every
// model (StressIntegrator::ImplicitReturn).
#pragma once

#include <cmath>
#include <limits>

#include "../config.hpp"
#include "../params.hpp"
#include "../state_check.hpp"
#include "../tensor.hpp"
#include "critical_state.hpp"
#include "elasticity.hpp"
#include "lode_shape.hpp"
#include "state.hpp"
#include "yield_state.hpp"

namespace granflow {

// Elastic predictor (detail::elastic_predictor, elasticity.hpp), then a backward-Euler
// plastic corrector with the moduli of the trial state. With isotropic elasticity and radial
// deviatoric flow (A3) the corrected deviator keeps the direction of the trial deviator, so the
// Lode angle is the trial one and the return has two unknowns, p and dLambda:
//   R1 = p - p_tr + K_tr dLambda Dg(p, q, e1) = 0                   (volumetric)
//   R2 = q - max(p, p_min) g M_p(p, e1) h(eps_n + dLambda) = 0      (yield condition)
// with q = q_tr - 3 G_tr dLambda, both divided by p_tr + p_min. Newton with the exact Jacobian
// and step halving; converged when |R1| is within its tolerance (kVolResidual, or the round-off
// of R1's terms where that is larger: ReturnMapResidual) and the yield function in ratio form,
// q / max(p, p_min) - g M_p h, is within ftol. (R2 in that ratio form made Newton creep where
// q_tr / p_tr is large, about doubling p per iteration: a quarter more residual evaluations on
// average and three times as many updates above 30 in random low-pressure states.)
// A root with p <= 0 means the skeleton opened within the increment (tension cut-off).
// Unconditionally stable: a large increment at low pressure (the free surface of a flow, where
// 2 G deps can exceed p many times) costs a few iterations instead of hundreds of explicit
// substeps. First order in the increment; frictional_increment (substepping.hpp) is the accurate
// alternative.

namespace detail {

template <LodeShape L, class S>
struct ReturnMapResidual {
  const FrictionalParams<S>& mp;
  S p_tr, q_tr, x, K, G, eps_n, e1;
  // constants of the increment
  S scale = p_tr + mp.p_min, inv_scale = S(1) / scale, inv_p_at = S(1) / mp.p_at;
  S tan_c = std::tan(mp.phi_c), log_eref_e1 = std::log(mp.e_ref / e1);

  struct Value {
    S R1, R2, q;
    S f;  // yield residual r - G M_p h: the convergence measure (R2 = f max(p, p_min) / scale)
    S dR1_dp, dR1_dL, dR2_dp, dR2_dL;  // exact Jacobian
    S R1_tol;  // tolerance of |R1|: kVolResidual, or R1's round-off where that is larger
  };

  // Three divisions besides the two cone ratios', one log and three exp (each evaluation is a
  // chain of dependent operations; a GPU warp of returns waits for its longest chain).
  GF_HDI Value operator()(S p, S dL) const {
    Value v;
    v.q = q_tr - S(3) * G * dL;
    const bool floored = !(p > mp.p_min);
    const S pe = floored ? mp.p_min : p;
    const S inv_pe = S(1) / pe;
    const S r = v.q * inv_pe;
    // ln(e_c / e1) with e_c of Eq. (16): both angles from one power of p and two exp.
    const S xpow = std::exp(mp.xi * std::log(pe * inv_p_at));
    const S lr = log_eref_e1 - mp.lambda_c * xpow;
    const S tan_p = std::exp(mp.n_p * lr) * tan_c;
    const S tan_pt = std::exp(-mp.n_d * lr) * tan_c;
    const ConeRatio<S> cp = cone_ratio<L>(x, tan_p), cpt = cone_ratio<L>(x, tan_pt);
    const S Gm = cp.gM;
    const S Dg = mp.A_d * (cpt.gM - r);
    const S eps = eps_n + dL;
    const S inv_kp_eps = S(1) / (mp.k_p + eps);
    const S h = eps * inv_kp_eps;
    v.R1 = (p - p_tr + K * dL * Dg) * inv_scale;
    // R1 cannot be resolved below the rounding of its terms: Dg is a difference of two ratios
    // of order one, times K dL, which at low pressure is many times p. In float a return that
    // had converged in f kept |R1| at 1-5 times kVolResidual, no step improved it, and it went
    // through the 1D returns. In the 5 mm column's replayed returns this tolerance alone took
    // the mean cost from 3.71 to 3.10 evaluations and the expected largest of 32 from 21.3 to
    // 10.4 (docs/benchmarks.md, "Plastic returns: the tail, and the cut"). For double the
    // bound is below kVolResidual unless K dL exceeds about 300 p.
    const S noise = S(16) * std::numeric_limits<S>::epsilon() *
                    (std::fabs(p) + p_tr + K * dL * mp.A_d * (cpt.gM + std::fabs(r))) * inv_scale;
    v.R1_tol = noise > Tolerances<S>::kVolResidual ? noise : Tolerances<S>::kVolResidual;
    v.f = r - Gm * h;
    v.R2 = (v.q - pe * Gm * h) * inv_scale;
    // p enters through r = q / p and ln(e_c/e1) (both frozen below the floor p_min).
    const S dlr_dp = floored ? S(0) : -mp.lambda_c * mp.xi * xpow * inv_pe;
    const S dr_dp = floored ? S(0) : -r * inv_pe;
    const S dGm_dp = cp.dgM_dtan * mp.n_p * tan_p * dlr_dp;
    const S dGpt_dp = cpt.dgM_dtan * (-mp.n_d) * tan_pt * dlr_dp;
    const S dr_dL = S(-3) * G * inv_pe;
    v.dR1_dp = (S(1) + K * dL * mp.A_d * (dGpt_dp - dr_dp)) * inv_scale;
    v.dR1_dL = K * (Dg - mp.A_d * dL * dr_dL) * inv_scale;
    v.dR2_dp = -((floored ? S(0) : Gm) + pe * dGm_dp) * h * inv_scale;
    v.dR2_dL = (S(-3) * G - pe * Gm * mp.k_p * inv_kp_eps * inv_kp_eps) * inv_scale;
    return v;
  }
};

// Fallback of the return map when the two-unknown Newton iteration stalls: a step across the
// kink of the moduli and e_c at p_min (or near the apex) that no step length improves. Such an
// iteration crept through hundreds of halved steps at the free surface of a flow (over 1,000
// residual evaluations for one update), and a GPU warp waits for its slowest point.
//
// 1. Floored branch. Below p_min the moduli and e_c do not depend on p, so R2 is a function of
//    dLambda alone, convex (h is concave) and decreasing from R2(0) > 0 to
//    R2(dL_max) = -p_min G M_p h < 0: Newton from dLambda = 0 climbs monotonically to its one root,
//    and R1 = 0 gives p explicitly. That root is the return wherever its p <= p_min (most often
//    p <= 0: the skeleton opens within the increment).
// 2. Otherwise, bracketed. For a fixed dLambda, R1 is strictly increasing in p (dR1/dp >= 1 /
//    scale: Dg falls with p through r = q / p and rises through M_pt; below p_min it is linear),
//    so p(dLambda) is unique and found by Newton safeguarded by its sign bracket.
//    g(dLambda) = R2(p(dLambda), dLambda) is positive at 0 (the trial state lies outside the yield
//    surface) and negative at dL_max (q = 0), so Newton on g with its derivative along
//    R1 = 0, safeguarded by bisection of [0, dL_max], always converges.
template <class Residual, class S>
GF_HDI bool floored_return(const Residual& res, S dL_max, S ftol, S& p, S& dL, typename Residual::Value& v,
                           int& evaluations) {
  S x = S(0);
  for (int it = 0; it < 40; ++it) {
    v = res(S(0), x);  // p = 0: every p-dependence frozen at p_min
    ++evaluations;
    // Monotone from below: R2 >= 0 up to round-off, so a negative value is converged too.
    if (std::fabs(v.f) <= ftol || (it > 0 && !(v.R2 > S(0)))) {
      dL = x;
      p = -v.R1 * res.scale;  // R1 is linear in p with slope 1 / scale
      return p <= res.mp.p_min;
    }
    if (!(v.dR2_dL < S(0))) return false;
    S next = x - v.R2 / v.dR2_dL;
    if (!(next <= dL_max)) next = dL_max;
    if (!(next > x)) {  // round-off: the iterate no longer moves
      dL = x;
      p = -v.R1 * res.scale;
      return std::fabs(v.f) <= S(1e3) * ftol && p <= res.mp.p_min;
    }
    x = next;
  }
  return false;
}

// p(dLambda): the root of R1 in p for a fixed dLambda. R1 is linear up to p_min (slope 1 /
// scale) and steeper above (its slope jumps by orders of magnitude at p_min, then falls with p),
// so an iterate at or below p_min gives the floored root p_f exactly: it is the answer if
// p_f <= p_min, and otherwise an upper bound of a root in (p_min, p_f]. Newton safeguarded by
// the sign bracket, with false position (Illinois) where a step leaves it. Above p_min the
// Newton step is taken on p R1 instead of R1: the dilatancy term K dL A_d q / p makes R1
// hyperbolic in p (Newton from below about doubles p per step), while p R1 is nearly the
// quadratic p^2 - p_tr p + K dL A_d (g M_pt p - q). Same root and sign; on 200,000 random
// states with increments up to 0.1 the pressure solves of the bracketed return need 4.3
// instead of 5.2 evaluations, and the updates' 99.9th percentile 57 instead of 66.
template <class Residual, class S>
GF_HDI bool pressure_for_multiplier(const Residual& res, S dL, S& p, typename Residual::Value& v, int& evaluations) {
  constexpr S kInf = std::numeric_limits<S>::infinity();
  const S p_min = res.mp.p_min;
  S lo = -kInf, hi = kInf, r_lo = 0, r_hi = 0;
  int side = 0;  // which end moved last (+1: hi, -1: lo), for the Illinois halving
  for (int it = 0; it < 60; ++it) {
    v = res(p, dL);
    ++evaluations;
    if (std::fabs(v.R1) <= v.R1_tol) return true;
    S next = p - v.R1 / v.dR1_dp;
    if (p > p_min) {
      const S dphi_dp = v.R1 + p * v.dR1_dp;  // d(p R1)/dp
      if (dphi_dp > S(0)) next = p - p * v.R1 / dphi_dp;
    } else {  // floored: linear in p, and nothing else depends on p
      if (!(next > p_min)) {
        p = next;
        v.R1 = S(0);
        return true;
      }
      lo = p_min;
      r_lo = (p_min - next) * v.dR1_dp;
      hi = next;
      r_hi = S(0);  // an upper bound: R1(next) >= 0
      side = 0;
      next = S(0.5) * (lo + hi);
      if (next == p) return false;
      p = next;
      continue;
    }
    if (v.R1 > S(0)) {
      hi = p;
      r_hi = v.R1;
      if (side == 1) r_lo *= S(0.5);
      side = 1;
    } else {
      lo = p;
      r_lo = v.R1;
      if (side == -1) r_hi *= S(0.5);
      side = -1;
    }
    // Round-off: a step below a few ulps of p (R1 is resolved only to its rounding, which in
    // float can exceed the tolerance) ends the solve.
    const bool at_round_off = std::fabs(next - p) <= S(8) * std::numeric_limits<S>::epsilon() * (std::fabs(p) + p_min);
    if (!(next > lo && next < hi)) {
      if (!(hi < kInf)) return at_round_off;
      next = lo > -kInf && r_hi > r_lo ? lo - r_lo * (hi - lo) / (r_hi - r_lo) : S(0.5) * (p_min + hi);
      if (!(next > lo && next < hi)) next = S(0.5) * (lo + hi);
    }
    if (next == p || at_round_off) return true;
    p = next;
  }
  return false;
}

// From the guess (p, dL); on return (p, dL, v) hold the last iterate, converged or not.
template <class Residual, class S>
GF_HDI bool bracketed_return(const Residual& res, S dL_max, S ftol, S& p, S& dL,
                             typename Residual::Value& v, int& evaluations) {
  S a = S(0), b = dL_max;  // g(a) > 0 > g(b)
  if (!(dL > a && dL < b)) dL = S(0.5) * (a + b);
  for (int it = 0; it < 80; ++it) {
    if (!pressure_for_multiplier(res, dL, p, v, evaluations)) return false;
    if (std::fabs(v.f) <= ftol || !(b - a > S(4) * std::numeric_limits<S>::epsilon() * dL_max)) return true;
    if (v.R2 > S(0)) a = dL;
    else b = dL;
    const S dp_dL = -v.dR1_dL / v.dR1_dp;  // along the curve R1 = 0
    const S dg = v.dR2_dL + v.dR2_dp * dp_dL;
    S next = dL - v.R2 / dg;
    if (!(next > a && next < b)) next = S(0.5) * (a + b);
    if (it == 79) return false;  // (p, dL) stay the last iterate
    p += dp_dL * (next - dL);  // tangent predictor for the next pressure solve
    dL = next;
  }
  return false;
}

enum class NewtonEnd {
  Converged,
  Liquefied,  // stalled at the pressure floor with the balance asking for less: p := 0
  Stalled,    // no halving of a step improved the residual, or the iterations ran out
  Singular    // a singular Jacobian (no hand-over)
};

// Newton iterations, and halvings of one Newton step, before the 1D returns take over. A
// converging Newton iteration needs 2-7 iterations and rarely a halving. One halving rather
// than three: a step that one halving does not improve is seldom improved by more (5 mm column
// ensemble: the stalled returns' cost fell from 7.0 to 3.5 evaluations before the hand-over,
// the expected largest cost of 32 plastic returns from 8.5 to 7.9).
inline constexpr int kNewtonIterations = 12, kHalvingsPerStep = 1, kRestartIterations = 6;

// Newton on (R1, R2) from (p, dL, v) with step halving on |R1| + |R2| and 0 <= dL <= dL_max. On
// return (p, dL, v) hold the last accepted iterate and p_before the pressure before the step
// that stalled.
template <class Residual, class S>
GF_HDI NewtonEnd newton_return(const Residual& res, S dL_max, S ftol, int max_it, S& p, S& dL,
                               typename Residual::Value& v, S& p_before, int& evaluations, int& halvings) {
  const S p_min = res.mp.p_min;
  for (int it = 0; it <= max_it; ++it) {
    if (std::fabs(v.R1) <= v.R1_tol && std::fabs(v.f) <= ftol) return NewtonEnd::Converged;
    if (it == max_it) return NewtonEnd::Stalled;
    const S a11 = v.dR1_dp, a12 = v.dR1_dL;
    const S a21 = v.dR2_dp, a22 = v.dR2_dL;
    const S det = a11 * a22 - a12 * a21;
    if (!(std::fabs(det) > S(0))) return NewtonEnd::Singular;
    const S dp = (-v.R1 * a22 + v.R2 * a12) / det;
    const S ddl = (-v.R2 * a11 + v.R1 * a21) / det;
    const S norm0 = std::fabs(v.R1) + std::fabs(v.R2);
    p_before = p;
    S lam = S(1);
    bool moved = false;
    for (int ls = 0; ls <= kHalvingsPerStep && !moved; ++ls, lam *= S(0.5)) {
      S dl_try = dL + lam * ddl;
      dl_try = dl_try < S(0) ? S(0) : (dl_try > dL_max ? dL_max : dl_try);
      const auto vt = res(p + lam * dp, dl_try);
      ++evaluations;
      halvings += ls > 0;
      if (std::fabs(vt.R1) + std::fabs(vt.R2) < norm0) {  // false for a non-finite trial
        p += lam * dp;
        dL = dl_try;
        v = vt;
        moved = true;
      }
    }
    if (!moved) return NewtonEnd::Stalled;
    if (p < S(2) * p_min && v.R1 > v.R1_tol && p_before + dp <= S(0) && std::fabs(p - p_before) < S(1e-3) * p_min) {
      // Stalled at the pressure floor while the volumetric balance asks for less (the full
      // Newton step leads to p <= 0): the return passes through zero pressure (liquefaction
      // within the increment). A converged iterate, or one still converging to a positive
      // pressure (slowly where the root lies near the kink of the moduli at p_min), is not a
      // stall. (Testing only R1 > 0 and a small step here reset about half of all converged
      // returns below 2 p_min to zero stress, so a stress-free skeleton compressed in small
      // increments never built up pressure: constitutive test
      // ReturnMapBuildsPressureFromZeroStressInSmallIncrements.)
      p = S(0);
      return NewtonEnd::Liquefied;
    }
  }
  return NewtonEnd::Stalled;
}

}  // namespace detail

template <LodeShape L, UpdatePart P = UpdatePart::Full, class S>
GF_HDI UpdateInfo frictional_return_map(const FrictionalParams<S>& mp, FrictionalState<S>& st, const Mat3In<S>& deps) {
  UpdateInfo inf;
  inf.substeps = 1;
  const S e0 = st.e;
  const S e1 = void_ratio_after(e0, trace(deps));
  if (frictional_state_fault(st.sigma, st.eps_pd, e0) != StateFault::None || !admissible_void_ratio(e1)) {
    inf.flags |= info::kInadmissible;
    return inf;
  }
  Mat3<S> sigma = st.sigma;
  const S p_n = mean_pressure(sigma);
  if (!(p_n > S(0))) sigma = Mat3<S>::Zero();
  if (!(p_n > mp.p_min)) inf.flags |= info::kPressureFloor;
  const Mat3<S> trial = detail::elastic_predictor(mp, sigma, e0, e1, deps);
  const S p_tr = mean_pressure(trial);
  if (!(p_tr > S(0))) {  // the skeleton opens: tension cut-off
    st.sigma = Mat3<S>::Zero();
    st.e = e1;
    inf.flags |= info::kTensionCutoff;
    return inf;
  }
  const YieldState<S> yt = yield_state<L>(mp, trial, st.eps_pd, e1, deps);
  if (!(yt.f > mp.ftol)) {
    st.sigma = trial;
    st.e = e1;
    return inf;
  }
  if constexpr (P == UpdatePart::ElasticOnly) {  // only yt.f was needed: the rest is dead code
    inf.flags |= info::kDeferred;
    return inf;
  }
  const StressInvariants<S> inv = stress_invariants(trial, deps);
  const detail::ReturnMapResidual<L, S> res{mp, p_tr, inv.q, inv.x, yt.C.K, yt.C.G, st.eps_pd, e1};
  // Start from the trial pressure and one linearised plastic correction.
  S p = p_tr;
  const S denom0 = ddot(yt.n, apply_elastic(yt.C, yt.m)) + yt.Gm * yt.dh;
  S dL = denom0 > S(0) ? yt.f / denom0 : S(0);
  if (!(dL > S(0))) dL = S(0);
  const S dL_max = inv.q / (S(3) * yt.C.G);  // q >= 0
  if (dL > dL_max) dL = dL_max;
  auto v = res(p, dL);
  int evaluations = 1, halvings = 0;
  inf.flags |= info::kPlasticReturn;
  S p_before = p;
  const detail::NewtonEnd end =
      detail::newton_return(res, dL_max, mp.ftol, detail::kNewtonIterations, p, dL, v, p_before, evaluations, halvings);
  bool converged = end == detail::NewtonEnd::Converged || end == detail::NewtonEnd::Liquefied;
  if (end == detail::NewtonEnd::Stalled) {
    inf.flags |= info::kFlooredReturn;
    converged = detail::floored_return(res, dL_max, mp.ftol, p, dL, v, evaluations);
    if (!converged && std::isfinite(p)) {
      // The floored root lies above p_min, where the 2D problem is smooth: Newton from there
      // converged for five of six such returns of the 5 mm column ensemble, in two to three
      // evaluations, against about 25 for the bracketed return.
      S p_f = p, dL_f = dL, unused = p;
      auto v_f = res(p_f, dL_f);
      ++evaluations;
      const detail::NewtonEnd again =
          detail::newton_return(res, dL_max, mp.ftol, detail::kRestartIterations, p_f, dL_f, v_f, unused, evaluations, halvings);
      if (again == detail::NewtonEnd::Converged || again == detail::NewtonEnd::Liquefied) {
        p = p_f;
        dL = dL_f;
        v = v_f;
        converged = true;
      }
    }
    if (!converged) {
      inf.flags |= info::kBracketedReturn;
      p = p_before;
      converged = detail::bracketed_return(res, dL_max, mp.ftol, p, dL, v, evaluations);
    }
  }
  inf.substeps = evaluations;  // residual evaluations: the cost of the update
  inf.halvings = halvings;
  if (!converged && std::isfinite(dL) && p < S(2) * mp.p_min) {
    // No root found within a few Pa of zero pressure, where the moduli and e_c have their
    // kink at p_min: the return ends at the cut-off (an error of at most 2 p_min in p). The
    // explicit fallback would cost a GPU warp hundreds of substeps for these few pascals
    // (1 mm column: 0.005 % of the updates made the mean step 2.6 times slower).
    p = S(0);
    converged = true;
  }
  if (!converged) {
    // Not seen in 520,000 random states (tests ReturnMapCostIsBoundedNearZeroPressure and
    // FloatPrecision.*; increments up to 0.1): the bracketed return ends by bisection at round-off.
    // The last iterate is kept and flagged. (The explicit substepping that used to complete such
    // a return doubled the GPU kernel's local-memory spills for code that never ran: the fused
    // G2P + constitutive kernel needs 254 registers and 696 B of spills with it, 240 and none
    // without; frictional_increment stays the integrator of StressIntegrator::Substepping.)
    if (!std::isfinite(p) || !std::isfinite(dL)) {
      inf.flags |= info::kNonFinite;
      return inf;
    }
    inf.flags |= info::kReturnUnconverged;
  }
  st.eps_pd += dL;
  st.e = e1;
  if (!(p > S(0))) {  // the return passes through zero pressure: cut-off
    st.sigma = Mat3<S>::Zero();
    inf.flags |= info::kTensionCutoff;
    return inf;
  }
  st.sigma = v.q * inv.s_hat - p * identity3<S>();
  if (!all_finite(st.sigma)) inf.flags |= info::kNonFinite;
  return inf;
}

}  // namespace granflow
