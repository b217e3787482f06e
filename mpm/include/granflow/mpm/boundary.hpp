// Boundary conditions of the grid update besides the held components of the node masks:
// Coulomb friction at walls and at the base polyline, and a gate lifted at a finite speed.
// Frictional terrain (3D) is a pass of its own after the grid update, over a list of nodes
// and normals made at set-up (TerrainNode): scenes without it run the grid update unchanged.
//
// A stage's boundary is one block of bytes (SceneSetup::stage_masks, uploaded as it is): one
// mask byte per node (bit d: velocity component d held at zero; kContactNode: the node goes
// through contact_node), then, where the scene has friction or the stage a lifting or
// cylindrical gate, a
// ContactTable at the next 16-byte boundary, followed by its base segments. Which walls, base
// segment or gate act on a flagged node is decided from the node's position with the same
// predicates make_setup uses, so there is one definition of "held" for host and device.
#pragma once

#include <cmath>
#include <cstdint>

#include "layout.hpp"

namespace granflow::mpm {

// Mask bit of a node that goes through contact_node (bits 0 to D - 1: components held).
inline constexpr std::uint8_t kContactNode = 0x80;

// A wall with Coulomb friction: nodes on and beyond `position` along `axis`.
struct FrictionWall {
  int axis = 0;
  int at_max = 0;  // 0: bounds the domain from below (x <= position)
  double position = 0;
  double mu = 0;
};

// One segment of the base polyline y = b(x), x0 < x1.
struct BaseSegment {
  double x0, y0, x1, y1;
};

struct ContactTable {
  double origin[3] = {0, 0, 0};  // node coordinates origin + I h, as make_setup computes them
  double h = 0;
  double tol = 0;  // of the "on or beyond" tests (make_setup: 1e-9 h)
  int n_walls = 0;
  int n_segments = 0;  // of the frictional base (2D), stored after the table
  FrictionWall walls[6];
  double base_mu = 0;
  // Gate (gate != kNoGate; a plane gate held whole goes by the masks alone): the plane's
  // half-space (x - point) . normal >= 0, or the nodes at and outside the vertical cylinder of
  // gate_radius about point; lifted (lift_speed > 0), only at and above its lower edge, which
  // is at point's height (y) at lift_start and rises at lift_speed.
  int gate = 0;
  int gate_bits = 0;    // components it holds
  int gate_radial = 0;  // a cylinder holding the radial component (hold = "normal")
  double gate_point[3] = {0, 0, 0}, gate_normal[3] = {0, 0, 0};
  double gate_radius = 0;
  double lift_speed = 0, lift_start = 0;
};

inline constexpr int kNoGate = 0, kPlaneGate = 1, kCylinderGate = 2;

GF_HDI long contact_table_offset(long n_nodes) { return (n_nodes + 15) / 16 * 16; }

template <class S>
GF_HDI const ContactTable& contact_table(const GridView<S>& gv) {
  return *reinterpret_cast<const ContactTable*>(gv.mask + contact_table_offset(gv.block > 0 ? gv.block : gv.n));
}
GF_HDI const BaseSegment* base_segments(const ContactTable& c) { return reinterpret_cast<const BaseSegment*>(&c + 1); }

// ---- where a boundary acts (host and device) ---------------------------------------------

GF_HDI bool beyond_wall(int axis, bool at_max, double position, const double* x, double tol) {
  return at_max ? x[axis] >= position - tol : x[axis] <= position + tol;
}

// Segment of the polyline at abscissa x: -1 before the first vertex, n past the last (the base
// continues level there), else the first segment with x <= x1.
GF_HDI int base_segment_at(const BaseSegment* s, int n, double x) {
  if (x <= s[0].x0) return -1;
  if (x >= s[n - 1].x1) return n;
  for (int i = 0; i < n; ++i)
    if (x <= s[i].x1) return i;
  return n;
}

GF_HDI double base_height(const BaseSegment* s, int n, int i, double x) {
  if (i < 0) return s[0].y0;
  if (i >= n) return s[n - 1].y1;
  return s[i].y0 + (s[i].y1 - s[i].y0) * (x - s[i].x0) / (s[i].x1 - s[i].x0);
}

// Height of the lifting gate's lower edge at time t.
GF_HDI double gate_edge(const ContactTable& c, double t) {
  return c.gate_point[1] + c.lift_speed * (t - c.lift_start);
}

GF_HDI bool in_gate_halfspace(const double* point, const double* normal, const double* x, int dim, double tol) {
  double s = 0;
  for (int d = 0; d < dim; ++d) s += (x[d] - point[d]) * normal[d];
  return s >= -tol;
}

// On or outside the vertical cylinder of radius r about the axis through point (3D).
GF_HDI bool outside_gate_cylinder(const double* point, double r, const double* x, double tol) {
  const double dx = x[0] - point[0], dz = x[2] - point[2];
  const double rr = r - tol;
  return dx * dx + dz * dz >= rr * rr;
}

GF_HDI bool gate_holds(const ContactTable& c, const double* x, int dim, double t) {
  if (c.gate == kNoGate) return false;
  const bool region = c.gate == kCylinderGate ? outside_gate_cylinder(c.gate_point, c.gate_radius, x, c.tol)
                                              : in_gate_halfspace(c.gate_point, c.gate_normal, x, dim, c.tol);
  return region && (c.lift_speed == 0 || x[1] >= gate_edge(c, t) - c.tol);
}

// ---- the contact condition ---------------------------------------------------------------

// Coulomb contact with a rigid wall of outward normal n (into the wall), applied to the trial
// velocity v of a node (Bardenhagen, Brackbill & Sulsky 2000, CMAME 187:529): a node moving
// into the wall (v.n > 0) loses its normal velocity, and its tangential velocity is reduced
// by at most mu times that change, never reversed; a separating node is left free.
// mu = 0 is free slip for approaching nodes (bitwise for axis-aligned normals), large mu
// no slip.
template <int D, class S>
GF_HDI void coulomb_contact(S* v, const double* n, double mu) {
  S vn = S(0);
  for (int d = 0; d < D; ++d) vn += v[d] * S(n[d]);
  if (!(vn > S(0))) return;
  S vt2 = S(0);
  for (int d = 0; d < D; ++d) {
    v[d] -= vn * S(n[d]);
    vt2 += v[d] * v[d];
  }
  const S vt = std::sqrt(vt2);
  const S slip = vt - S(mu) * vn;  // tangential speed left
  const S keep = slip > S(0) ? slip / vt : S(0);
  for (int d = 0; d < D; ++d) v[d] *= keep;
}

// Velocity of a flagged node after the stage's masks: friction of every frictional wall the
// node lies on or beyond (in scene order), then of the base, then the hold of a lifting or
// cylindrical gate (t: time at the start of the step).
template <int D, class S>
GF_HDI void contact_node(const GridView<S>& gv, long I, const GridDesc<D, S>& g, double t) {
  using G = GridLayout<D>;
  const ContactTable& c = contact_table(gv);
  double x[3] = {0, 0, 0};
  int Im[D];
  g.multi(I, Im);
  for (int d = 0; d < D; ++d) x[d] = c.origin[d] + static_cast<double>(Im[d]) * c.h;
  S v[D];
  for (int d = 0; d < D; ++d) v[d] = gv.f(G::VNEW + d, I);
  for (int w = 0; w < c.n_walls; ++w) {
    const FrictionWall& fw = c.walls[w];
    if (!beyond_wall(fw.axis, fw.at_max != 0, fw.position, x, c.tol)) continue;
    double n[3] = {0, 0, 0};
    n[fw.axis] = fw.at_max ? 1.0 : -1.0;
    coulomb_contact<D, S>(v, n, fw.mu);
  }
  if constexpr (D == 2) {
    if (c.n_segments > 0) {
      const BaseSegment* s = base_segments(c);
      const int i = base_segment_at(s, c.n_segments, x[0]);
      if (x[1] <= base_height(s, c.n_segments, i, x[0]) + c.tol) {
        double n[3] = {0, -1, 0};  // level beyond the ends
        if (i >= 0 && i < c.n_segments) {
          const double dx = s[i].x1 - s[i].x0, dy = s[i].y1 - s[i].y0, len = std::sqrt(dx * dx + dy * dy);
          n[0] = dy / len;
          n[1] = -dx / len;
        }
        coulomb_contact<D, S>(v, n, c.base_mu);
      }
    }
  }
  if (gate_holds(c, x, D, t)) {
    if constexpr (D == 3) {
      if (c.gate_radial) {  // the radial component, both ways (as a plane gate's normal)
        const double dx = x[0] - c.gate_point[0], dz = x[2] - c.gate_point[2];
        const double r = std::sqrt(dx * dx + dz * dz);  // >= gate_radius - tol > 0
        const S nx = S(dx / r), nz = S(dz / r);
        const S vr = v[0] * nx + v[2] * nz;
        v[0] -= vr * nx;
        v[2] -= vr * nz;
      }
    }
    for (int d = 0; d < D; ++d)
      if (c.gate_bits & (1 << d)) v[d] = S(0);
  }
  for (int d = 0; d < D; ++d) gv.f(G::VNEW + d, I) = v[d];
}

// ---- frictional terrain (3D) ---------------------------------------------------------------

// A node on or just below the terrain and the ground's normal into the ground at its plan
// position (from the raster's slope); make_setup lists them once (SceneSetup::terrain).
struct TerrainNode {
  long node = 0;
  double n[3] = {0, 0, 0};
};

// Coulomb friction with the ground on a listed node's velocity after the grid update (and after
// the masks and contacts of walls and gates that also hold it).
template <int D, class S>
GF_HDI void terrain_contact(const GridView<S>& gv, const TerrainNode& t, double mu) {
  using G = GridLayout<D>;
  S v[D];
  for (int d = 0; d < D; ++d) v[d] = gv.f(G::VNEW + d, t.node);
  coulomb_contact<D, S>(v, t.n, mu);
  for (int d = 0; d < D; ++d) gv.f(G::VNEW + d, t.node) = v[d];
}

// ---- obstacles ----------------------------------------------------------------------------

// A node inside a rigid obstacle or on its surface, with the normal (into the obstacle) of the
// nearest face; make_setup lists them once (SceneSetup::obstacle_nodes). mu < 0: no-slip.
struct ObstacleNode {
  long node = 0;
  double n[3] = {0, 0, 0};
  double mu = -1;
};

// The obstacle's hold on a listed node's velocity after the grid update (and after the walls,
// base, gates and terrain that also hold it): no-slip, or Coulomb contact with its face.
template <int D, class S>
GF_HDI void obstacle_contact(const GridView<S>& gv, const ObstacleNode& o) {
  using G = GridLayout<D>;
  if (o.mu < 0) {
    for (int d = 0; d < D; ++d) gv.f(G::VNEW + d, o.node) = S(0);
    return;
  }
  S v[D];
  for (int d = 0; d < D; ++d) v[d] = gv.f(G::VNEW + d, o.node);
  coulomb_contact<D, S>(v, o.n, o.mu);
  for (int d = 0; d < D; ++d) gv.f(G::VNEW + d, o.node) = v[d];
}

// ---- forces on the boundaries ----------------------------------------------------------------

// A node some boundary holds, measured for the force on it (SceneSetup::probes): the node, the
// part of a boundary it counts for (a node held by several counts for the first in scene
// order), the part's outward normal there (into the boundary) and the node's position.
struct ForceProbe {
  long node = 0;
  int part = 0;
  double n[3] = {0, 0, 0};
  double x[3] = {0, 0, 0};
};

// Sums over the steps since the last Runner::take_forces of one part or boundary. dp: the
// momentum the boundary's nodes removed from the material in a step (its force times dt; per
// unit width in 2D). A step's own sums use impulse, normal, tangential and moment only.
struct ForceSums {
  double impulse[3] = {0, 0, 0};      // sum of dp [N s]
  double normal = 0, tangential = 0;  // sums of dp . n and |dp - (dp . n) n|, node by node
  double moment[3] = {0, 0, 0};       // sum of (x - moment point) x dp (2D: z only)
  double max_force = 0;               // largest |sum of dp| / dt of one step [N]
  double time = 0;                    // sum of dt
  long steps = 0;
};

// Adds a probe's dp of this step to its part's step sums (moments about `about`).
template <int D>
GF_HDI void add_probe_momentum(ForceSums& step, const ForceProbe& p, const double* dp, const double* about) {
  double dn = 0;
  for (int d = 0; d < D; ++d) {
    step.impulse[d] += dp[d];
    dn += dp[d] * p.n[d];
  }
  double t2 = 0;
  for (int d = 0; d < D; ++d) {
    const double t = dp[d] - dn * p.n[d];
    t2 += t * t;
  }
  step.normal += dn;
  step.tangential += std::sqrt(t2);
  double r[3] = {0, 0, 0};
  for (int d = 0; d < D; ++d) r[d] = p.x[d] - about[d];
  if constexpr (D == 2) {
    step.moment[2] += r[0] * dp[1] - r[1] * dp[0];
  } else {
    step.moment[0] += r[1] * dp[2] - r[2] * dp[1];
    step.moment[1] += r[2] * dp[0] - r[0] * dp[2];
    step.moment[2] += r[0] * dp[1] - r[1] * dp[0];
  }
}

// Adds one step's sums (of a part, or of a boundary: its parts' step sums added) to the sums
// since the last take.
GF_HDI void add_force_step(ForceSums& acc, const ForceSums& step, double dt) {
  double f2 = 0;
  for (int d = 0; d < 3; ++d) {
    acc.impulse[d] += step.impulse[d];
    acc.moment[d] += step.moment[d];
    f2 += step.impulse[d] * step.impulse[d];
  }
  acc.normal += step.normal;
  acc.tangential += step.tangential;
  const double f = std::sqrt(f2) / dt;
  if (f > acc.max_force) acc.max_force = f;
  acc.time += dt;
  acc.steps += 1;
}

GF_HDI void add_step_sums(ForceSums& a, const ForceSums& b) {
  for (int d = 0; d < 3; ++d) {
    a.impulse[d] += b.impulse[d];
    a.moment[d] += b.moment[d];
  }
  a.normal += b.normal;
  a.tangential += b.tangential;
}

}  // namespace granflow::mpm
