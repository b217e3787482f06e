// Node masks and contact lists: walls, base, gates and terrain held per stage, contact tables, terrain nodes.
#include "scene/node_masks.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <limits>
#include <string>

#include <granflow/mpm/boundary.hpp>

#include "scene/setup_common.hpp"

namespace granflow::mpm::detail {
namespace {

// Terrain: nodes on or below the ground (evaluated at the nearest point of the footprint) are
// held, the same in every stage. No-slip: all components, by the masks. Frictional: the nodes
// a point on or above the ground can reach (quadratic stencils reach 1.5 h per axis; on a
// slope |grad b| a node that far aside lies up to 1.5 h (1 + sqrt 2 |grad b|) below the
// ground) go through the terrain pass with the ground's normal there; deeper nodes are held
// whole by the masks. terrain.contact = "support" (the default) lists as well every node above
// the ground whose shape function's support the ground cuts: its support reaches down to
// y - h (linear hats) or y - 1.5 h (quadratic B-splines), not below the row of a level ground
// where modified splines end; the node takes the contact law (Coulomb, or for no-slip ground
// a stick while it moves into the ground) instead of moving freely with a cell that the ground
// leaves part empty (issue 51: creep, sinking). Returns the mask of the held nodes; lists the
// contact nodes in su.terrain and, when `forces`, every node within a stencil's reach in
// ground_nodes.
std::vector<std::uint8_t> terrain_nodes(const Scene& sc, SceneSetup& su, const Surface& ground, bool forces,
                                        double tol, std::vector<TerrainNode>& ground_nodes) {
  const int D = sc.dim;
  std::vector<std::uint8_t> ground_mask(su.n_nodes, 0);
  const std::uint8_t all = static_cast<std::uint8_t>((1u << D) - 1);
  const bool frictional = sc.terrain->mu.has_value();
  const bool floored = std::any_of(sc.walls.begin(), sc.walls.end(), [](const Wall& w) { return w.axis == 1 && !w.at_max; });
  const bool support = sc.terrain->contact == Terrain::Contact::Support;
  const int* nd = su.nodes.data();
  auto ground_at_column = [&](int kx, int kz, double& xc, double& zc) {
    xc = std::clamp(su.origin[0] + kx * sc.h, sc.origin[0], sc.origin[0] + sc.size[0]);
    zc = std::clamp(su.origin[2] + kz * sc.h, sc.origin[2], sc.origin[2] + sc.size[2]);
    return ground.height(xc, zc);
  };
  double low = std::numeric_limits<double>::max(), high = -low;  // the ground's range over the footprint
  for (int kz = 0; kz < nd[2]; ++kz)
    for (int kx = 0; kx < nd[0]; ++kx) {
      double xc, zc;
      const double b = ground_at_column(kx, kz, xc, zc);
      low = std::min(low, b);
      high = std::max(high, b);
    }
  // A level ground is an axis-aligned floor: boundary-modified quadratic B-splines there, as at
  // a y- wall at its height (any other terrain keeps truncated splines; docs/mpm_terrain.md).
  const bool modified = sc.shape == ShapeKind::QuadraticBSpline && sc.modified_boundary_splines && high - low <= tol;
  const int floor_row = static_cast<int>(std::floor((high - su.origin[1]) / sc.h + 1e-9));
  const double reach = sc.shape == ShapeKind::Linear ? sc.h : 1.5 * sc.h;  // a shape's support below its node
  double g2 = 0, most_into = -std::numeric_limits<double>::max();  // gravity's largest component into the ground
  for (int d = 0; d < 3; ++d) g2 += sc.gravity[d] * sc.gravity[d];
  for (int kz = 0; kz < nd[2]; ++kz)
    for (int kx = 0; kx < nd[0]; ++kx) {
      double xc, zc;
      const double b = ground_at_column(kx, kz, xc, zc);
      if (!floored && b < sc.origin[1] - tol)
        fail("grid.origin", "the terrain at x = " + fmt(xc) + ", z = " + fmt(zc) + " (y = " + fmt(b) +
                                ") lies below the grid (y from " + fmt(sc.origin[1]) +
                                "): lower grid.origin[1] or raise terrain.origin[2]");
      double nrm[3] = {0, -1, 0};
      const double slope = ground.normal(xc, zc, nrm);
      most_into = std::max(most_into, sc.gravity[0] * nrm[0] + sc.gravity[1] * nrm[1] + sc.gravity[2] * nrm[2]);
      const double band = 2 * sc.h * (1 + std::sqrt(2.0) * slope);  // reach of a stencil (frictional ground, force probes)
      for (int ky = 0; ky < nd[1]; ++ky) {
        const double y = su.origin[1] + ky * sc.h;
        const bool above = y > b + tol;
        if (above) {
          const double lowest = modified ? std::max(y - reach, su.origin[1] + floor_row * sc.h) : y - reach;
          if (!support || !(lowest < b - tol)) break;
        }
        const long I = kx + static_cast<long>(nd[0]) * (ky + static_cast<long>(nd[1]) * kz);
        if (forces && b - y <= band) ground_nodes.push_back({I, {nrm[0], nrm[1], nrm[2]}});
        if (above || (frictional && b - y <= band))
          su.terrain.push_back({I, {nrm[0], nrm[1], nrm[2]}});
        else
          ground_mask[I] = all;
      }
    }
  if (g2 > 0 && !(most_into > 1e-9 * std::sqrt(g2)))
    fail("solver.gravity", "is parallel to the terrain or points away from it everywhere (its largest component into the "
                    "ground is " + fmt(most_into) + " m/s^2): nothing would hold the material on it");
  std::sort(su.terrain.begin(), su.terrain.end(), [](const TerrainNode& a, const TerrainNode& b) { return a.node < b.node; });
  if (modified) {
    AxisWalls& a = su.walls[1];
    a.lo = a.has_lo ? std::max(a.lo, floor_row) : floor_row;
    a.has_lo = true;
  }
  // no-slip ground: the listed nodes above it stick while they move into it
  su.terrain_mu = frictional ? *sc.terrain->mu : std::numeric_limits<double>::infinity();
  return ground_mask;
}

// One stage's node mask: per node the components held (a bit per axis) and kContactNode where
// a frictional wall or base or a lifting gate acts; with friction or a lifting gate the stage's
// ContactTable and the base's segments follow the nodes (boundary.hpp).
std::vector<std::uint8_t> stage_mask(const Scene& sc, const SceneSetup& su, const Stage& st, int gate_axis,
                                     bool lifting, bool friction, const std::vector<std::uint8_t>& ground_mask,
                                     double tol, double stage_start) {
  const int D = sc.dim;
  std::vector<std::uint8_t> mask(su.n_nodes, 0);
  const std::uint8_t all = static_cast<std::uint8_t>((1u << D) - 1);
  const bool cylinder = st.gate && st.gate->radius > 0;
  // a cylinder's "normal" is radial: contact_node holds it (gate_radial), no axis bit
  const std::uint8_t gate_bits =
      st.gate ? (st.gate->normal_only ? (cylinder ? std::uint8_t(0) : static_cast<std::uint8_t>(1u << gate_axis)) : all)
              : 0;
  for (long k = 0; k < su.n_nodes; ++k) {
    long kk = k;
    double x[3];
    for (int d = 0; d < D; ++d) {
      x[d] = su.origin[d] + (kk % su.nodes[d]) * sc.h;
      kk /= su.nodes[d];
    }
    std::uint8_t m = 0;
    bool contact = false;
    for (const Wall& w : sc.walls) {
      if (!beyond_wall(w.axis, w.at_max, w.position, x, tol)) continue;
      if (w.mu)
        contact = true;
      else
        m |= w.no_slip ? all : static_cast<std::uint8_t>(1u << w.axis);
    }
    if (sc.base && x[1] <= polyline(sc.base->x, sc.base->y, x[0]) + tol) {
      if (sc.base->mu)
        contact = true;
      else
        m |= all;
    }
    if (st.gate) {
      const bool held = cylinder ? outside_gate_cylinder(st.gate->point.data(), st.gate->radius, x, tol)
                                 : in_gate_halfspace(st.gate->point.data(), st.gate->normal.data(), x, D, tol);
      if (held) {
        if (lifting || cylinder)
          contact = true;
        else
          m |= gate_bits;
      }
    }
    if (!ground_mask.empty()) m |= ground_mask[k];
    if (contact && m != all) m |= kContactNode;
    mask[k] = m;
  }
  if (friction || lifting || cylinder) {
    ContactTable c;
    for (int d = 0; d < D; ++d) c.origin[d] = su.origin[d];
    c.h = sc.h;
    c.tol = tol;
    for (const Wall& w : sc.walls)
      if (w.mu) c.walls[c.n_walls++] = FrictionWall{w.axis, w.at_max ? 1 : 0, w.position, *w.mu};
    std::vector<BaseSegment> segments;
    if (sc.base && sc.base->mu) {
      for (size_t i = 1; i < sc.base->x.size(); ++i)
        segments.push_back({sc.base->x[i - 1], sc.base->y[i - 1], sc.base->x[i], sc.base->y[i]});
      c.n_segments = static_cast<int>(segments.size());
      c.base_mu = *sc.base->mu;
    }
    if (lifting || cylinder) {
      c.gate = cylinder ? kCylinderGate : kPlaneGate;
      c.gate_bits = gate_bits;
      c.gate_radial = cylinder && st.gate->normal_only;
      for (int d = 0; d < D; ++d) {
        c.gate_point[d] = st.gate->point[d];
        if (!cylinder) c.gate_normal[d] = st.gate->normal[d];
      }
      c.gate_radius = st.gate->radius;
      c.lift_speed = st.gate->lift_speed;
      c.lift_start = stage_start;
    }
    const size_t at = static_cast<size_t>(contact_table_offset(su.n_nodes));
    const size_t seg_bytes = segments.size() * sizeof(BaseSegment);
    mask.resize(at + sizeof c + seg_bytes, 0);
    std::memcpy(mask.data() + at, &c, sizeof c);
    if (seg_bytes) std::memcpy(mask.data() + at + sizeof c, segments.data(), seg_bytes);
  }
  return mask;
}

}  // namespace

std::vector<TerrainNode> setup_node_masks(const Scene& sc, SceneSetup& su, const std::optional<Surface>& ground,
                                          bool forces) {
  const int D = sc.dim;
  const int nmat = sc.material_count();
  for (const Wall& w : sc.walls)
    for (const Wall& o : sc.walls)
      if (w.axis == o.axis && !w.at_max && o.at_max && !(w.position < o.position))
        fail(o.key, "this wall and " + w.key + " leave no room between them");
  su.has_boundary = !sc.walls.empty() || sc.base.has_value() || sc.terrain.has_value() || !sc.obstacles.empty();
  // Wall node rows for the boundary-modified quadratic B-splines: the last held node row of
  // each axis-aligned wall (the flume's inclined base and the gates keep truncated splines).
  su.walls.assign(D, AxisWalls{});
  if (sc.shape == ShapeKind::QuadraticBSpline && sc.modified_boundary_splines) {
    for (const Wall& w : sc.walls) {
      const double c = (w.position - su.origin[w.axis]) / sc.h;
      AxisWalls& a = su.walls[w.axis];
      if (w.at_max) {
        a.hi = static_cast<int>(std::ceil(c - 1e-9));
        a.has_hi = true;
      } else {
        a.lo = static_cast<int>(std::floor(c + 1e-9));
        a.has_lo = true;
      }
    }
  }
  for (const Stage& st : sc.stages) su.has_boundary = su.has_boundary || st.gate.has_value();
  // Several materials run the ensembles' kernels (kernels.hpp, Members), compiled only with
  // boundary code: a scene of several materials without a wall, a base or a gate gets masks
  // that hold no node (and no contact table), which its update reads as no boundary.
  const bool masks = su.has_boundary || nmat > 1;
  // Friction and lifting gates: their nodes are flagged (kContactNode) and a ContactTable
  // follows the stage's masks (boundary.hpp).
  const bool friction = std::any_of(sc.walls.begin(), sc.walls.end(), [](const Wall& w) { return w.mu.has_value(); }) ||
                        (sc.base && sc.base->mu);
  int frictional_walls = 0;
  for (const Wall& w : sc.walls) {
    if (!w.mu) continue;
    const std::string key = w.key.substr(0, w.key.rfind('.')) + ".mu";
    if (!(*w.mu >= 0)) fail(key, "must be >= 0, got " + fmt(*w.mu));
    if (++frictional_walls > static_cast<int>(std::size(ContactTable{}.walls)))
      fail(key, "at most one frictional wall per side of the grid");
  }
  if (sc.base && sc.base->mu && !(*sc.base->mu >= 0)) fail("base.mu", "must be >= 0, got " + fmt(*sc.base->mu));
  const double tol = 1e-9 * sc.h;
  std::vector<std::uint8_t> ground_mask;
  std::vector<TerrainNode> ground_nodes;  // every node on or below the ground (force probes)
  if (ground) ground_mask = terrain_nodes(sc, su, *ground, forces, tol, ground_nodes);
  double stage_start = 0;  // as the driver sums the stage durations
  for (size_t si = 0; si < sc.stages.size(); ++si) {
    const Stage& st = sc.stages[si];
    int gate_axis = -1;
    const bool lifting = st.gate && st.gate->lift_speed != 0;
    if (st.gate && !(st.gate->lift_speed >= 0))
      fail("stage[" + std::to_string(si) + "].gate.lift_speed", "must be >= 0 (0: held whole while the stage lasts), got " + fmt(st.gate->lift_speed));
    if (st.gate && st.gate->radius != 0) {
      const std::string key = "stage[" + std::to_string(si) + "].gate.";
      if (D != 3) fail(key + "radius", "a cylindrical gate needs a 3D scene");
      if (!(st.gate->radius >= sc.h))
        fail(key + "radius", "must be at least the grid spacing h = " + fmt(sc.h) + " m, got " + fmt(st.gate->radius));
      if (!st.gate->normal.empty()) fail(key + "normal", "a cylindrical gate (radius) has no normal: its axis is vertical through point");
    } else if (st.gate) {
      int nz = 0;
      for (int d = 0; d < D; ++d)
        if (st.gate->normal[d] != 0) { ++nz; gate_axis = d; }
      if (nz == 0) fail("stage[" + std::to_string(si) + "].gate.normal", "must not be zero");
      if (st.gate->normal_only && nz != 1)
        fail("stage[" + std::to_string(si) + "].gate.hold",
             "\"normal\" needs an axis-aligned normal; use \"all\" for an inclined gate");
      if (lifting && st.gate->normal[1] != 0)
        fail("stage[" + std::to_string(si) + "].gate.lift_speed",
             "a gate is lifted along y: its normal must have no y component (a vertical gate)");
    }
    std::vector<std::uint8_t> mask;
    if (masks) mask = stage_mask(sc, su, st, gate_axis, lifting, friction, ground_mask, tol, stage_start);
    su.stage_masks.push_back(std::move(mask));
    stage_start += st.duration;
  }
  return ground_nodes;
}

}  // namespace granflow::mpm::detail
