// Particle seeding (make_setup's helpers): the bodies' material points, their initial stress, the step's limit.
#pragma once

#include <optional>
#include <vector>

#include <granflow/mpm/runner.hpp>

#include "scene/surface.hpp"

namespace granflow::mpm::detail {

// Checks the materials (at most 255, one model) and returns each one's bulk density at rest.
std::vector<double> rest_densities(const Scene& sc);

// Seeds the bodies on the lattice of spacing su.spacing (boxes and polygons aligned with their
// lower corner, release volumes between surfaces), checks that no point starts in a held region
// (beyond a wall, under the base or the terrain `ground`), and fills su.particles, point_body,
// point_material and the seeded and geometric volumes. Needs the grid (su.n_nodes).
void seed_particles(const Scene& sc, SceneSetup& su, const std::vector<double>& rho0s,
                    const std::optional<Surface>& ground);

// The geostatic initial stress (scene's initial.geostatic) of the seeded points, from the free
// surface above each lattice column; returns the deepest point's depth below it.
double initial_stress(const Scene& sc, SceneSetup& su, const std::vector<double>& rho0s);

// Stability of a fixed step (su.dt_estimate): the P-wave speed at depth_max, the smallest limit of
// the materials; checks time.dt against it.
void step_estimate(const Scene& sc, SceneSetup& su, const std::vector<double>& rho0s, double depth_max);

}  // namespace granflow::mpm::detail
