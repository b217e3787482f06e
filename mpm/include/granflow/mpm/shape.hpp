// Shape functions, tensor products of a 1D kernel. r = (x - x_I) / h; a particle at grid
// coordinate xi touches the K nodes base(xi) .. base(xi) + K - 1 along each axis.
#pragma once

#include <cmath>

#include <granflow/constitutive/config.hpp>

namespace granflow::mpm {

enum class ShapeKind { Linear, QuadraticBSpline };

// Linear hat (the paper's choice): C0, gradients jump when a particle crosses a cell face.
struct LinearShape {
  static constexpr int K = 2;
  static constexpr ShapeKind kind = ShapeKind::Linear;
  template <class S>
  static GF_HDI int base(S xi) { return static_cast<int>(std::floor(xi)); }
  template <class S>
  static GF_HDI S w(S r) {
    const S a = std::fabs(r);
    return a < S(1) ? S(1) - a : S(0);
  }
  // Derivative in r; at r = 0 the particle's own base node takes -1 so the K gradients
  // of one particle always sum to zero (partition of unity).
  template <class S>
  static GF_HDI S dw(S r) {
    if (r >= S(0)) return r < S(1) ? S(-1) : S(0);
    return r > S(-1) ? S(1) : S(0);
  }
};

// Quadratic B-spline: C1, removes the cell-crossing noise of the linear hat.
struct QuadraticShape {
  static constexpr int K = 3;
  static constexpr ShapeKind kind = ShapeKind::QuadraticBSpline;
  template <class S>
  static GF_HDI int base(S xi) { return static_cast<int>(std::floor(xi - S(0.5))); }
  template <class S>
  static GF_HDI S w(S r) {
    const S a = std::fabs(r);
    if (a < S(0.5)) return S(0.75) - a * a;
    if (a < S(1.5)) return S(0.5) * (S(1.5) - a) * (S(1.5) - a);
    return S(0);
  }
  template <class S>
  static GF_HDI S dw(S r) {
    const S a = std::fabs(r);
    if (a < S(0.5)) return S(-2) * r;
    if (a < S(1.5)) return r > S(0) ? -(S(1.5) - a) : (S(1.5) - a);
    return S(0);
  }
};

}  // namespace granflow::mpm
