// Pressure-dependent elasticity of the frictional part, Eq. (13) (MODEL.md 3.2).
#pragma once

#include <cmath>

#include "../config.hpp"
#include "../params.hpp"
#include "../tensor.hpp"

namespace granflow {

template <class S>
struct ElasticModuli {
  S K, G;
};

// x^n, with the common exponent n = 1/2 (both Table 3 sets) as a square root: pow is the most
// expensive operation of the stress update on CPU and GPU alike.
template <class S>
GF_HDI S pow_exponent(S x, S n) {
  return n == S(0.5) ? std::sqrt(x) : std::pow(x, n);
}

// K_f = K0 p_at (2.97 - e)^2 / (1 + e) (p/p_at)^n with p floored at p_min (MODEL.md 3.2, A5);
// G_f = 3 K (1 - 2 nu) / (2 (1 + nu)).
template <class S>
GF_HDI ElasticModuli<S> elastic_moduli(const FrictionalParams<S>& m, S p, S e) {
  const S pe = p > m.p_min ? p : m.p_min;
  const S a = S(kVoidRatioMax) - e;
  const S K = m.K0 * m.p_at * a * a / (S(1) + e) * pow_exponent(pe / m.p_at, m.n);
  return {K, S(3) * K * (S(1) - S(2) * m.nu) / (S(2) * (S(1) + m.nu))};
}

// C^e : X = K tr(X) I + 2 G dev(X)
template <class S>
GF_HDI Mat3<S> apply_elastic(const ElasticModuli<S>& c, const Mat3In<S>& X) {
  return c.K * trace(X) * identity3<S>() + S(2) * c.G * dev(X);
}

namespace detail {

// Elastic integration over deps with the pressure-dependent moduli (two-stage Heun).
template <class S>
GF_HDI Mat3<S> elastic_predictor(const FrictionalParams<S>& mp, const Mat3In<S>& sigma, S e, S e_end,
                                 const Mat3In<S>& deps) {
  const Mat3<S> d1 = apply_elastic(elastic_moduli(mp, mean_pressure(sigma), e), deps);
  const Mat3<S> d2 = apply_elastic(elastic_moduli(mp, mean_pressure<S>(sigma + d1), e_end), deps);
  return sigma + S(0.5) * (d1 + d2);
}

}  // namespace detail

}  // namespace granflow
