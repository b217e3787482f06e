// Admissibility of an update's input state. Every update checks its state with these before it
// starts (info::kInadmissible, state untouched); the interfaces that take a state from outside
// (Python, UMAT) call them too, to name the fault in their message.
#pragma once

#include <cmath>
#include <cstdint>

#include "config.hpp"
#include "params.hpp"
#include "tensor.hpp"

namespace granflow {

enum class StateFault : std::uint8_t {
  None = 0,
  Stress,         // a component of the frictional stress is NaN or infinite
  PlasticStrain,  // eps_pd NaN, infinite or negative
  VoidRatio,      // e not in (0, kVoidRatioMax)
  Temperature     // s = sqrt(T) NaN, infinite or negative (T < 0 gives s = NaN)
};

template <class S>
GF_HDI bool admissible_void_ratio(S e) {
  return e > S(0) && e < S(kVoidRatioMax);
}

template <class S>
GF_HDI bool admissible_sqrt_temperature(S s) {
  return s >= S(0) && std::isfinite(s);
}

template <class S>
GF_HDI StateFault frictional_state_fault(const Mat3In<S>& sigma, S eps_pd, S e) {
  if (!all_finite(sigma)) return StateFault::Stress;
  if (!(eps_pd >= S(0)) || !std::isfinite(eps_pd)) return StateFault::PlasticStrain;
  if (!admissible_void_ratio(e)) return StateFault::VoidRatio;
  return StateFault::None;
}

}  // namespace granflow
