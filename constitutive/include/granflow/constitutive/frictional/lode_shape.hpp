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

// The cone's stress ratio g(theta; phi) M(phi) of a state-dependent angle given by its tangent,
// with the derivatives the return map and the consistency condition need. Equal to
// lode_factor and stress_ratio_of_angle of sin(phi) = t / sqrt(1 + t^2), rearranged to three
// divisions and three square roots (eleven and five as separate calls): on the GPU the return
// map's evaluations are latency-bound chains in which each IEEE division is a long link
// (about 20 dependent instructions in fp64).
template <class S>
struct ConeRatio {
  S gM;        // g M
  S dgM_dtan;  // d(g M) / d tan(phi)
  S dgM_dx;    // d(g M) / dx, x = sin(3 theta)
};

template <LodeShape L, class S>
GF_HDI ConeRatio<S> cone_ratio(S x, S tan_phi) {
  const S inv_sec = S(1) / std::sqrt(S(1) + tan_phi * tan_phi);  // cos(phi)
  const S sn = tan_phi * inv_sec;
  const S dsin_dtan = inv_sec * inv_sec * inv_sec;
  const S a = S(3) - sn, b = S(3) + sn;
  const S u = S(1) / (a * b);
  const S inv_a = b * u;
  const S M = S(6) * sn * inv_a;  // stress_ratio_of_angle
  const S dM_ds = S(18) * inv_a * inv_a;
  if constexpr (L == LodeShape::Circular) {
    return {M, dM_ds * dsin_dtan, S(0)};
  } else {
    const S c = a * a * u;  // (3 - sin) / (3 + sin)
    const S c2 = c * c, c4 = c2 * c2;
    const S inv_den = S(1) / (S(1) + c4 - (S(1) - c4) * x);
    const S g = std::sqrt(std::sqrt(S(2) * c4 * inv_den));
    const S dg_dx = S(0.25) * g * (S(1) - c4) * inv_den;
    const S dlng_dc = b * b * u - c2 * c * (S(1) + x) * inv_den;  // 1/c - c^3 (1 + x) / den
    const S dc_ds = S(-6) * a * a * u * u;                         // -6 / (3 + sin)^2
    const S dg_ds = g * dlng_dc * dc_ds;
    return {g * M, (g * dM_ds + M * dg_ds) * dsin_dtan, M * dg_dx};
  }
}

}  // namespace granflow
