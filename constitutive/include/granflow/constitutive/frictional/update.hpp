// The frictional update from a velocity gradient: objective rotation (MODEL.md 3.1, A6) and
// the material increment.
#pragma once

#include "../config.hpp"
#include "../params.hpp"
#include "../tensor.hpp"
#include "return_map.hpp"
#include "state.hpp"
#include "substepping.hpp"

namespace granflow {

// Full update from a velocity gradient: the Jaumann rotation (Hughes-Winget, MODEL.md 3.1 A6)
// and the material response to d eps = D dt, combined by Strang splitting (half rotation,
// material increment, half rotation). Rotating the whole step first (Lie splitting) would make
// the update first order in dt in any loading with spin, such as simple shear.
// UpdatePart::ElasticOnly defers plastic steps of the return map; the substepping integrators
// always do the whole update.
template <LodeShape L, StressIntegrator I = StressIntegrator::ImplicitReturn, UpdatePart P = UpdatePart::Full,
          class S>
GF_HDI UpdateInfo frictional_update(const FrictionalParams<S>& mp, FrictionalState<S>& st, const Mat3In<S>& grad_v,
                                    S dt) {
  const Mat3<S> W = skew(grad_v);
  const Mat3<S> Q = hughes_winget_rotation(W, S(0.5) * dt);
  FrictionalState<S> trial = st;
  trial.sigma = Q * st.sigma * Q.transpose();
  const Mat3<S> deps = sym(grad_v) * dt;
  UpdateInfo inf;
  if constexpr (I == StressIntegrator::ImplicitReturn) {
    inf = frictional_return_map<L, P>(mp, trial, deps);
    if (inf.deferred()) return inf;
  } else {
    inf = frictional_increment<L, I == StressIntegrator::Hybrid>(mp, trial, deps);
  }
  trial.sigma = Q * trial.sigma * Q.transpose();
  if (inf.ok()) st = trial;
  return inf;
}

}  // namespace granflow
