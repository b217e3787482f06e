// make_setup: the scene's checks and grid, then its parts in order (seeding, node masks, obstacles, probes).
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <granflow/mpm/runner.hpp>

#include "scene/boundaries.hpp"
#include "scene/mesh_geometry.hpp"
#include "scene/node_masks.hpp"
#include "scene/seeding.hpp"
#include "scene/setup_common.hpp"
#include "scene/surface.hpp"

namespace granflow::mpm {
namespace {

constexpr int kPad = 3;  // grid cells added around the scene box (walls sit inside the grid)
constexpr double kMaxNodes = 4e8;
constexpr double kMaxMapCells = 1e7;  // maps' cells over the footprint (about 50 bytes each while written)

// Smallest map cell over the largest |scene coordinate|: positions resolve 2.2e-16 (fp64) or
// 1.2e-7 (fp32 storage) times it, so a cell spans at least 450,000 or 840 distinct positions.
double min_cell_over_coordinate(Precision p) { return p == Precision::FP64 ? 1e-10 : 1e-4; }

}  // namespace

SceneSetup make_setup(const Scene& sc) {
  using detail::fail;
  using detail::fmt;
  SceneSetup su;
  su.scene = sc;
  const int D = sc.dim;
  if (D != 2 && D != 3) fail("grid.dim", "must be 2 or 3");
  if (!(sc.h > 0)) fail("grid.h", "must be positive");
  if (sc.ppc_axis < 1) fail("particles.per_cell", "must be at least 1");
  if (sc.stages.empty()) fail("stage", "at least one [[stage]] is required");
  if (sc.pic_speed < 0) fail("solver.pic_speed", "must not be negative");
  if (sc.pic_speed > 0)
    for (size_t i = 0; i < sc.stages.size(); ++i)
      if (sc.stages[i].flip)
        fail("stage[" + std::to_string(i) + "].flip",
             "a FLIP fraction per step cannot be combined with solver.pic_speed (a rate)");
  if (static_cast<int>(sc.gravity.size()) != D) fail("gravity", "needs " + std::to_string(D) + " components");
  const double l = sc.h / sc.ppc_axis;
  su.spacing = l;

  // Grid, padded by kPad cells on every side.
  su.origin.resize(D);
  su.nodes.resize(D);
  su.n_nodes = 1;
  double nodes_wanted = 1;
  for (int d = 0; d < D; ++d) nodes_wanted *= sc.size[d] / sc.h + 1 + 2 * kPad;
  if (!(nodes_wanted <= kMaxNodes))
    fail("grid.h", "h = " + fmt(sc.h) + " m gives a grid of " + fmt(nodes_wanted) + " nodes (about " +
                       detail::gb(detail::memory_bytes(D, nodes_wanted, 0, sc.stages.size())) + "); at most " +
                       std::to_string(static_cast<long>(kMaxNodes)) +
                       " nodes are allowed (grid.size / grid.h + 7 per axis): use a larger grid.h or a smaller "
                       "grid.size");
  for (int d = 0; d < D; ++d) {
    const double cells = sc.size[d] / sc.h;
    if (std::fabs(cells - std::round(cells)) > 1e-6)
      fail("grid.size", "each extent must be a whole number of cells of grid.h = " + fmt(sc.h));
    su.origin[d] = sc.origin[d] - kPad * sc.h;
    su.nodes[d] = static_cast<int>(std::lround(cells)) + 1 + 2 * kPad;
    su.n_nodes *= su.nodes[d];
  }

  // Terrain (3D): the raster covers the grid's footprint in plan (x, z).
  std::optional<detail::Surface> ground;
  if (sc.terrain) {
    const Terrain& t = *sc.terrain;
    if (D != 3) fail("terrain", "needs grid.dim = 3 (a 2D scene takes its ground as base)");
    if (!t.raster) fail("terrain.file", "no raster was read");
    if (t.origin.size() != 3) fail("terrain.origin", "needs 3 components (easting, northing, elevation)");
    if (t.mu && !(std::isfinite(*t.mu) && *t.mu >= 0)) fail("terrain.mu", "must be a finite number >= 0, got " + fmt(*t.mu));
    ground.emplace(*t.raster, t.origin);
    const std::string miss = ground->uncovered(sc.origin[0], sc.origin[0] + sc.size[0], sc.origin[2],
                                               sc.origin[2] + sc.size[2]);
    if (!miss.empty())
      fail("terrain.file", miss + ", the grid's footprint (grid.origin and grid.size in x and z, plus terrain.origin)");
  }

  // Maps (output/maps.cpp): a 2D profile's bins or the 3D map cells over the footprint, counted
  // before they are allocated, and resolvable in the positions' precision. Scene coordinates are
  // the georeferenced ones minus terrain.origin, so what counts is what remains after that shift.
  if ((D == 2 && sc.base) || (D == 3 && ground)) {
    const bool set = sc.output.map_cell > 0;
    const std::string key = set ? "output.map_cell" : (D == 2 ? "grid.h" : "terrain.file");
    const double cell = set ? sc.output.map_cell : (D == 2 ? sc.h : sc.terrain->raster->cellsize);
    double cells = 1, reach = 0;
    for (int d = 0; d < D; d += 2) {  // x (and z): the plan axes
      cells *= std::ceil(sc.size[d] / cell) + (D == 3 ? 1 : 0);  // in 3D the cells may straddle both edges
      reach = std::max({reach, std::fabs(sc.origin[d]), std::fabs(sc.origin[d] + sc.size[d])});
    }
    const std::string what = "map cells of " + fmt(cell) + " m" + (set ? "" : " (" + key + "; output.map_cell sets them)");
    if (!(cells <= kMaxMapCells))
      fail(key, what + " give " + fmt(cells) + " cells over the grid's footprint (about " + detail::gb(50 * cells) +
                    " while the maps are written); at most " + std::to_string(static_cast<long>(kMaxMapCells)) +
                    " are allowed: set a larger output.map_cell");
    const double k = min_cell_over_coordinate(sc.precision);
    if (!(cell >= k * reach))
      fail(key, what + " at scene coordinates up to " + fmt(reach) + " m: " + precision_name(sc.precision) +
                    " positions resolve " + fmt(reach * (sc.precision == Precision::FP64 ? 2.2e-16 : 1.2e-7)) +
                    " m there, and map cells must be at least " + fmt(k) + " x the largest |x| or |z| of the grid (" +
                    fmt(k * reach) + " m; 1e-10 x in fp64, 1e-4 x in fp32 and mixed): bring grid.origin" +
                    (D == 3 ? " and terrain.origin nearer the material" : " nearer 0") + " or use larger cells");
  }

  // Particles on a lattice of spacing h / ppc_axis (scene/seeding.cpp), their initial stress and
  // the stable step at rest.
  const std::vector<double> rho0s = detail::rest_densities(sc);
  detail::seed_particles(sc, su, rho0s, ground);
  const double depth_max = detail::initial_stress(sc, su, rho0s);
  detail::step_estimate(sc, su, rho0s, depth_max);
  if (sc.output.series_dt < sc.dt * (1 - 1e-12))  // steps land on every sample
    fail("output.series_dt", "is " + fmt(sc.output.series_dt) + " s, below time.dt = " + fmt(sc.dt) +
                                 " s: steps land on every sample, so the run would take dt / series_dt times as many "
                                 "steps; give series_dt >= time.dt");

  // Node masks per stage, contact tables, terrain nodes (scene/node_masks.cpp).
  const bool forces = sc.output.forces_on(!sc.obstacles.empty());
  std::vector<TerrainNode> ground_nodes = detail::setup_node_masks(sc, su, ground, forces);

  detail::ObstacleMeshes meshes;
  detail::MeshHeldNodes held;
  if (!sc.obstacles.empty()) {
    meshes = detail::obstacle_meshes(sc, su);
    detail::setup_obstacles(sc, su, meshes, held);
  }
  if (forces) {
    std::sort(ground_nodes.begin(), ground_nodes.end(), [](const TerrainNode& a, const TerrainNode& b) { return a.node < b.node; });
    detail::setup_force_probes(sc, su, ground_nodes, meshes, held);
  }

  // Tracked particles: nearest to the requested points.
  const HostParticles& hp = su.particles;
  const long n = hp.n;
  for (const Track& t : sc.tracks) {
    long best = 0;
    double bd = std::numeric_limits<double>::max();
    for (long i = 0; i < n; ++i) {
      double d2 = 0;
      for (int d = 0; d < D; ++d) d2 += (hp.x[d * n + i] - t.x[d]) * (hp.x[d * n + i] - t.x[d]);
      if (d2 < bd) { bd = d2; best = i; }
    }
    su.tracked.push_back(best);
  }
  return su;
}

}  // namespace granflow::mpm
