// Second-order tensor helpers on Eigen fixed-size 3x3 matrices.
// Convention (MODEL.md 1.1): tensors tension-positive; p and eps_v compression-positive.
#pragma once

#include <Eigen/Core>
#include <cmath>

#include "config.hpp"

namespace granflow {

template <class S>
using Mat3 = Eigen::Matrix<S, 3, 3>;

namespace detail {
template <class T>
struct type_identity {
  using type = T;
};
}  // namespace detail

// A Mat3 parameter that takes part in no template deduction, so Eigen expressions convert.
template <class S>
using Mat3In = typename detail::type_identity<Mat3<S>>::type;

template <class S>
GF_HDI Mat3<S> identity3() {
  return Mat3<S>::Identity();
}

template <class S>
GF_HDI S trace(const Mat3<S>& a) {
  return a(0, 0) + a(1, 1) + a(2, 2);
}

template <class S>
GF_HDI S ddot(const Mat3<S>& a, const Mat3<S>& b) {
  return (a.cwiseProduct(b)).sum();
}

template <class S>
GF_HDI Mat3<S> sym(const Mat3<S>& a) {
  return S(0.5) * (a + a.transpose());
}

template <class S>
GF_HDI Mat3<S> skew(const Mat3<S>& a) {
  return S(0.5) * (a - a.transpose());
}

template <class S>
GF_HDI Mat3<S> dev(const Mat3<S>& a) {
  return a - (trace(a) / S(3)) * identity3<S>();
}

template <class S>
GF_HDI S det3(const Mat3<S>& a) {
  return a(0, 0) * (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1)) - a(0, 1) * (a(1, 0) * a(2, 2) - a(1, 2) * a(2, 0)) +
         a(0, 2) * (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0));
}

// Mean pressure, compression-positive: p = -tr(sigma)/3.
template <class S>
GF_HDI S mean_pressure(const Mat3<S>& sigma) {
  return -trace(sigma) / S(3);
}

// Von Mises deviatoric stress q = sqrt(3 J2).
template <class S>
GF_HDI S deviatoric_q(const Mat3<S>& sigma) {
  const Mat3<S> s = dev(sigma);
  return std::sqrt(S(1.5) * ddot(s, s));
}

// Lode measure x = sin(3 theta) = -(3 sqrt3 / 2) J3 / J2^(3/2), +1 in triaxial compression
// (tension-positive stress), -1 in triaxial extension (MODEL.md 3.4). 0 when J2 vanishes.
template <class S>
GF_HDI S sin3theta(const Mat3<S>& s_dev, S J2) {
  if (!(J2 > S(0))) return S(0);
  const S J3 = det3(s_dev);
  S x = -S(2.598076211353316) * J3 / (J2 * std::sqrt(J2));
  return x > S(1) ? S(1) : (x < S(-1) ? S(-1) : x);
}

// d sin3theta / d sigma (deviatoric tensor); zero when J2 is negligible.
template <class S>
GF_HDI Mat3<S> dsin3theta_dsigma(const Mat3<S>& s_dev, S J2) {
  if (!(J2 > S(0))) return Mat3<S>::Zero();
  const S J3 = det3(s_dev);
  const Mat3<S> dJ3 = dev<S>(s_dev * s_dev);  // d det(s) / d sigma = dev(s s)
  const S k = -S(2.598076211353316);
  const S J2_32 = J2 * std::sqrt(J2);
  return k * (dJ3 / J2_32 - S(1.5) * J3 / (J2_32 * J2) * s_dev);
}

// Rotation of the Hughes-Winget midpoint rule, Q = (I - W dt/2)^-1 (I + W dt/2).
// Q is exactly orthogonal for skew W, so sigma <- Q sigma Q^T integrates the Jaumann rate
// (second order in dt) and preserves every stress invariant exactly.
// Closed form of that Cayley transform: with A = W dt/2 and its axial vector a,
// Q = I + 2 (A + A^2) / (1 + |a|^2).
template <class S>
GF_HDI Mat3<S> hughes_winget_rotation(const Mat3<S>& W, S dt) {
  const Mat3<S> A = S(0.5) * dt * W;
  const S a2 = A(2, 1) * A(2, 1) + A(0, 2) * A(0, 2) + A(1, 0) * A(1, 0);
  return identity3<S>() + (S(2) / (S(1) + a2)) * (A + A * A);
}

template <class S>
GF_HDI bool all_finite(const Mat3<S>& a) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (!std::isfinite(a(i, j))) return false;
  return true;
}

}  // namespace granflow
