// The three models the drivers and the MPM instantiate, with one interface:
//   Model::Params, Model::State,
//   Model::update(params, state, grad_v, dt, stress) -> UpdateInfo   (the MPM's update;
//     Model::update<UpdatePart::ElasticOnly> may defer a plastic step, config.hpp)
//   Model::diagnostics(params, state, D)             -> Diagnostics  (what the figures plot)
// Frictional-only carries no temperature; collisional-only carries no skeleton stress.
// PhaseTransition is the parallel sum of Eq. (1): both parts see the same D (MODEL.md 2, 9).
#pragma once

#include "collisional.hpp"
#include "frictional.hpp"

namespace granflow {

template <class S>
struct Diagnostics {
  S p_f = 0, q_f = 0;  // frictional mean and deviatoric stress
  S p_c = 0, q_c = 0;  // collisional mean and deviatoric stress
  S K_col = 0;         // q_c / (q_c + q_f)
  S eta_c = 0;         // equivalent (collisional) shear viscosity
  S eps_pd = 0;        // equivalent plastic deviatoric strain
  S T = 0;             // granular temperature
  S e = 0;             // void ratio
};

// K_col = q_c / (q_c + q_f); 0 for a point without deviatoric stress (below 1e-9 Pa, where the
// ratio would only measure round-off).
template <class S>
GF_HDI S collisional_share(S q_c, S q_f) {
  const S sum = q_c + q_f;
  return sum > S(1e-9) ? q_c / sum : S(0);
}

template <class S, LodeShape L = LodeShape::SmoothMohrCoulomb, StressIntegrator I = StressIntegrator::ImplicitReturn>
struct FrictionalModel {
  using Scalar = S;
  using Params = FrictionalParams<S>;
  using State = FrictionalState<S>;
  static constexpr bool kFrictional = true, kCollisional = false;

  template <UpdatePart P = UpdatePart::Full>
  static GF_HDI UpdateInfo update(const Params& p, State& st, const Mat3In<S>& grad_v, S dt, Mat3<S>& stress) {
    const UpdateInfo inf = frictional_update<L, I, P>(p, st, grad_v, dt);
    stress = st.sigma;
    return inf;
  }
  static GF_HDI Diagnostics<S> diagnostics(const Params&, const State& st, const Mat3<S>&) {
    Diagnostics<S> d;
    d.p_f = mean_pressure(st.sigma);
    d.q_f = deviatoric_q(st.sigma);
    d.eps_pd = st.eps_pd;
    d.e = st.e;
    return d;
  }
};

template <class S, RestitutionUse R = RestitutionUse::Everywhere>
struct CollisionalModel {
  using Scalar = S;
  using Params = CollisionalParams<S>;
  using State = CollisionalState<S>;
  static constexpr bool kFrictional = false, kCollisional = true;

  template <UpdatePart = UpdatePart::Full>  // no plastic step to defer
  static GF_HDI UpdateInfo update(const Params& p, State& st, const Mat3In<S>& grad_v, S dt, Mat3<S>& stress) {
    return collisional_update<R>(p, st, grad_v, dt, stress);
  }
  static GF_HDI Diagnostics<S> diagnostics(const Params& p, const State& st, const Mat3In<S>& D) {
    Diagnostics<S> d;
    const KineticCoefficients<S> kc = kinetic_coefficients<R>(p, S(1) / (S(1) + st.e));
    const CollisionalTransport<S> t = collisional_transport(p, kc, st.s);
    const Mat3<S> sc = collisional_stress(t, D);
    d.p_c = mean_pressure(sc);
    d.q_c = deviatoric_q(sc);
    d.K_col = collisional_share(d.q_c, S(0));
    d.eta_c = t.eta;
    d.T = st.s * st.s;
    d.e = st.e;
    return d;
  }
};

template <class S>
struct PhaseTransitionState {
  Mat3<S> sigma_f = Mat3<S>::Zero();
  S eps_pd = 0;
  S e = 0;
  S s = 0;  // sqrt(T)
};

template <class S, LodeShape L = LodeShape::SmoothMohrCoulomb, RestitutionUse R = RestitutionUse::Everywhere,
          StressIntegrator I = StressIntegrator::ImplicitReturn>
struct PhaseTransitionModel {
  using Scalar = S;
  using Params = PhaseTransitionParams<S>;
  using State = PhaseTransitionState<S>;
  static constexpr bool kFrictional = true, kCollisional = true;

  // MODEL.md 9: Jaumann-rotated frictional update (which also advances e exactly), kinetic
  // functions at the new V_s, exact frozen-coefficient temperature update, then the sum.
  template <UpdatePart P = UpdatePart::Full>
  static GF_HDI UpdateInfo update(const Params& p, State& st, const Mat3In<S>& grad_v, S dt, Mat3<S>& stress) {
    UpdateInfo inf;
    if (!admissible_sqrt_temperature(st.s)) {  // first: also where the frictional step would defer
      inf.flags |= info::kInadmissible;
      return inf;
    }
    FrictionalState<S> fs{st.sigma_f, st.eps_pd, st.e};
    inf = frictional_update<L, I, P>(p.f, fs, grad_v, dt);
    if (!inf.ok()) return inf;
    const Mat3<S> D = sym(grad_v);
    const KineticCoefficients<S> kc = kinetic_coefficients<R>(p.c, S(1) / (S(1) + fs.e));
    if (kc.clamped) inf.flags |= info::kVsClamped;
    const S s1 = advance_sqrt_temperature(temperature_balance(p.c, kc, D, st.s), st.s, dt);
    const Mat3<S> sc = collisional_stress(collisional_transport(p.c, kc, s1), D);
    if (!std::isfinite(s1) || !all_finite(sc)) {
      inf.flags |= info::kNonFinite;
      return inf;
    }
    st.sigma_f = fs.sigma;
    st.eps_pd = fs.eps_pd;
    st.e = fs.e;
    st.s = s1;
    stress = fs.sigma + sc;
    return inf;
  }

  static GF_HDI Diagnostics<S> diagnostics(const Params& p, const State& st, const Mat3In<S>& D) {
    Diagnostics<S> d;
    d.p_f = mean_pressure(st.sigma_f);
    d.q_f = deviatoric_q(st.sigma_f);
    const KineticCoefficients<S> kc = kinetic_coefficients<R>(p.c, S(1) / (S(1) + st.e));
    const CollisionalTransport<S> t = collisional_transport(p.c, kc, st.s);
    const Mat3<S> sc = collisional_stress(t, D);
    d.p_c = mean_pressure(sc);
    d.q_c = deviatoric_q(sc);
    d.K_col = collisional_share(d.q_c, d.q_f);
    d.eta_c = t.eta;
    d.eps_pd = st.eps_pd;
    d.T = st.s * st.s;
    d.e = st.e;
    return d;
  }
};

}  // namespace granflow
