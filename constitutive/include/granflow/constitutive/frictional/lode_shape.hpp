// Deviatoric-plane shape g(theta) of the yield function and the flow rule (MODEL.md 3.4, A1).
#pragma once

#include <cmath>

#include "../config.hpp"

namespace granflow {

// Smooth Mohr-Coulomb shape of Sheng, Sloan & Yu (2000) and its partial derivatives
// with respect to x = sin(3 theta) and to sin(phi).
template <class S>
struct LodeFactor {
  S g, dg_dx, dg_dsin;
};

template <LodeShape L, class S>
GF_HDI LodeFactor<S> lode_factor(S x, S sin_phi) {
  if constexpr (L == LodeShape::Circular) {
    return {S(1), S(0), S(0)};
  } else {
    const S c = (S(3) - sin_phi) / (S(3) + sin_phi);
    const S c2 = c * c, c4 = c2 * c2;
    const S den = S(1) + c4 - (S(1) - c4) * x;
    const S g = std::sqrt(std::sqrt(S(2) * c4 / den));
    const S dg_dx = S(0.25) * g * (S(1) - c4) / den;
    // d ln g / d c = 1/c - c^3 (1 + x) / den ; d c / d sin = -6 / (3 + sin)^2
    const S dlng_dc = S(1) / c - c2 * c * (S(1) + x) / den;
    const S dc_ds = S(-6) / ((S(3) + sin_phi) * (S(3) + sin_phi));
    return {g, dg_dx, g * dlng_dc * dc_ds};
  }
}

}  // namespace granflow
