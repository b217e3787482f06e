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

// Walls of the background grid along one axis, for the boundary-modified quadratic B-splines:
// lo / hi are the node indices of a wall (the last held node row), used when the bit is set.
struct AxisWalls {
  int lo = 0, hi = 0;
  bool has_lo = false, has_hi = false;
};

// 1D weight and derivative (in r) of node i for a particle at grid coordinate xi.
//
// Linear hats are interpolatory: a wall node carries the whole weight of a point on the wall,
// so they are used unchanged. A quadratic B-spline is not: at a wall node, the truncated
// B-splines of the free nodes keep 1/8 of the weight (N_{lo+1}(x_lo) = 1/8), so a wall
// transmits only 7/8 of the stress of the material against it, and the discrete equilibrium
// puts the base stress of a consolidated column 1/0.875 = 1.14 times too high (measured 1.17).
// Boundary-modified B-splines: the ghost nodes beyond a wall are eliminated by linear
// extrapolation, v_{lo-k} = (1 + k) v_lo - k v_{lo+1} (k = 1, 2), i.e.
//   N~_lo = N_lo + 2 N_{lo-1} + 3 N_{lo-2},   N~_{lo+1} = N_{lo+1} - N_{lo-1} - 2 N_{lo-2},
// and zero beyond the wall. Inside the domain (x >= x_lo) this gives N~_lo = 1 - r on the
// first half cell and the standard spline beyond (C1 at r = 1/2), N~_{lo+1} = r then standard:
// non-negative, partition of unity and linear reproduction kept, interpolatory at the wall
// (N~_lo(x_lo) = 1, every free node's function vanishes there).
template <class Shape, class S>
GF_HDI void weight_1d(S xi, int i, const AxisWalls& a, S& w, S& dw) {
  w = Shape::w(xi - S(i));
  dw = Shape::dw(xi - S(i));
  if constexpr (Shape::kind == ShapeKind::QuadraticBSpline) {
    if ((a.has_lo && i < a.lo) || (a.has_hi && i > a.hi)) {
      w = dw = S(0);
      return;
    }
    auto ghost = [&](int g, S c) {
      w += c * Shape::w(xi - S(g));
      dw += c * Shape::dw(xi - S(g));
    };
    if (a.has_lo) {
      if (i == a.lo) { ghost(a.lo - 1, S(2)); ghost(a.lo - 2, S(3)); }
      if (i == a.lo + 1) { ghost(a.lo - 1, S(-1)); ghost(a.lo - 2, S(-2)); }
    }
    if (a.has_hi) {
      if (i == a.hi) { ghost(a.hi + 1, S(2)); ghost(a.hi + 2, S(3)); }
      if (i == a.hi - 1) { ghost(a.hi + 1, S(-1)); ghost(a.hi + 2, S(-2)); }
    }
  }
}

// Lowest stencil node along one axis; with walls, quadratic stencils stay between them (the
// modified functions vanish beyond a wall, and a point up to 1.5 cells beyond it keeps a
// partition of unity on the nodes inside).
template <class Shape, class S>
GF_HDI int stencil_base_1d(S xi, const AxisWalls& a) {
  int b = Shape::base(xi);
  if constexpr (Shape::kind == ShapeKind::QuadraticBSpline) {
    if (a.has_hi && b > a.hi - (Shape::K - 1)) b = a.hi - (Shape::K - 1);
    if (a.has_lo && b < a.lo) b = a.lo;
  }
  return b;
}

}  // namespace granflow::mpm
