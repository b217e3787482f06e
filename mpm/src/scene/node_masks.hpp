// Node masks and contact lists (make_setup's helpers): held nodes per stage, contact tables, terrain nodes.
#pragma once

#include <optional>
#include <vector>

#include <granflow/mpm/runner.hpp>

#include "scene/surface.hpp"

namespace granflow::mpm::detail {

// Checks the walls, the frictional walls and base and the stages' gates, and sets what the step
// holds: su.has_boundary, the wall rows of the boundary-modified quadratic B-splines (su.walls),
// the frictional terrain's nodes with the ground's normal (su.terrain, su.terrain_mu) and one node
// mask per stage, with its ContactTable where friction or a lifting gate acts (su.stage_masks).
// Returns the nodes on or below the terrain `ground` within a stencil's reach, with its normal,
// when `forces` (the force probes'; unsorted; empty without terrain).
std::vector<TerrainNode> setup_node_masks(const Scene& sc, SceneSetup& su, const std::optional<Surface>& ground,
                                          bool forces);

}  // namespace granflow::mpm::detail
