// Critical void ratio and the trigonometry of the state-dependent angles, Eqs. (16)-(18)
// (MODEL.md 3.3).
#pragma once

#include <cmath>

#include "../config.hpp"
#include "../params.hpp"

namespace granflow {

// e_c = e_ref exp(-lambda_c (p/p_at)^xi), Eq. (16); p floored at p_min.
template <class S>
GF_HDI S critical_void_ratio(const FrictionalParams<S>& m, S p) {
  const S pe = p > m.p_min ? p : m.p_min;
  return m.e_ref * std::exp(-m.lambda_c * std::pow(pe / m.p_at, m.xi));
}

// d e_c / d p (zero below the floor, where e_c is frozen).
template <class S>
GF_HDI S critical_void_ratio_dp(const FrictionalParams<S>& m, S p) {
  if (!(p > m.p_min)) return S(0);
  const S x = p / m.p_at;
  return -critical_void_ratio(m, p) * m.lambda_c * m.xi * std::pow(x, m.xi - S(1)) / m.p_at;
}

// sin(phi) from tan(phi) (cone_ratio, lode_shape.hpp, has it with its derivative).
template <class S>
GF_HDI S sin_of_tan(S t) {
  return t / std::sqrt(S(1) + t * t);
}

}  // namespace granflow
