// Set-up of the obstacles and of the boundary-force probes (make_setup's helpers).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <granflow/mpm/runner.hpp>

namespace granflow::mpm::detail {

class MeshSolid;
// Per obstacle its checked mesh (Shape::Mesh), else null.
using ObstacleMeshes = std::vector<std::shared_ptr<const MeshSolid>>;

// Checks the mesh obstacles once (closed, oriented, no crossings, in the grid, the thin-plate
// rule: docs/mpm_meshes.md) for the two calls below; scenes without a mesh get nulls only.
ObstacleMeshes obstacle_meshes(const Scene& sc, const SceneSetup& su);

// A node a mesh obstacle holds, with its nearest face's normal, part and distance: found once by
// setup_obstacles (in parallel) and read again by setup_force_probes.
struct MeshHeldNode {
  long node;
  double n[3];
  int part;
  double depth;
};
using MeshHeldNodes = std::vector<std::vector<MeshHeldNode>>;  // per obstacle (empty: not a mesh)

// Checks the scene's obstacles (size against the grid, material inside) and lists their nodes
// with the normal of the nearest face (SceneSetup::obstacle_nodes). Needs the particles seeded.
void setup_obstacles(const Scene& sc, SceneSetup& su, const ObstacleMeshes& meshes, MeshHeldNodes& held);

// Lists the nodes each boundary holds as force probes, grouped in parts (output.forces): the
// obstacles in scene order, the walls in scene order, the base, the terrain (its nodes with the
// ground's normal); a node held by several counts for the first of them. `ground` lists every node on or below
// the terrain (empty without one).
void setup_force_probes(const Scene& sc, SceneSetup& su, const std::vector<TerrainNode>& ground,
                        const ObstacleMeshes& meshes, const MeshHeldNodes& held);

}  // namespace granflow::mpm::detail
