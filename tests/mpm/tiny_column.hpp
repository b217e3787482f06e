// Small scenes of the MPM tests: the CI column on a 20 mm grid (200 points) with a larger step,
// and the consolidation block.
#pragma once

#include <string>

#include <granflow/mpm/layout.hpp>
#include <granflow/mpm/runner.hpp>
#include <granflow/mpm/scene.hpp>

namespace granflow::mpm::test {

// The grid of a set-up as the kernels see it (no walls), for tests that call kernels directly.
template <int D = 2>
GridDesc<D, double> grid_of(const SceneSetup& su) {
  GridDesc<D, double> g{};
  for (int d = 0; d < D; ++d) {
    g.origin[d] = su.origin[d];
    g.nodes[d] = su.nodes[d];
  }
  g.h = su.scene.h;
  g.inv_h = 1.0 / su.scene.h;
  g.n_nodes = su.n_nodes;
  g.nx = su.nodes[0];
  return g;
}

inline Scene tiny_column(ModelKind model, ShapeKind shape = ShapeKind::Linear) {
  Scene sc = small_column_scene(model, shape);
  sc.h = 0.02;
  sc.dt = 2e-4;
  sc.size = {0.60, 0.16};
  sc.stages[0].duration = 0.06;
  sc.stages[1].duration = 0.3;
  sc.output.times = {0.3};
  sc.output.series_dt = 0.01;
  return sc;
}

// The scene stripped to its grid, material and bodies: no walls, tracked points, frames or run-out
// line, and one stage `name` of `duration` with `damping`.
inline void one_open_stage(Scene& sc, const std::string& name, double duration, double damping = 0) {
  sc.walls.clear();
  sc.tracks.clear();
  sc.output.times.clear();
  sc.runout_x.clear();
  sc.runout_y.clear();
  Stage s;
  s.name = name;
  s.duration = duration;
  s.damping = damping;
  sc.stages = {s};
}

// A 20 x 10 cm block between two free-slip walls on a no-slip floor, stress free at t = 0,
// loaded by damped gravity for 0.08 s (no gate, a token second stage): the consolidation check.
inline Scene consolidation_block(ModelKind model = ModelKind::Frictional) {
  Scene sc = small_column_scene(model);
  sc.size = {0.2, 0.15};
  sc.walls[1].position = 0.2;
  sc.bodies[0].box_max = {0.2, 0.1};
  sc.dt = 1e-4;
  sc.stages[0].gate.reset();
  sc.stages[0].duration = 0.08;
  sc.stages[1].duration = 1e-4;
  sc.output.times.clear();
  return sc;
}

}  // namespace granflow::mpm::test
