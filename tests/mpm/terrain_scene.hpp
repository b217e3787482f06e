// The 3D terrain scenes of the terrain tests (test_mpm_terrain.cpp, test_mpm_terrain_contact.cpp).
#pragma once

#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include <granflow/io/raster.hpp>
#include <granflow/mpm/runner.hpp>
#include <granflow/mpm/scene.hpp>

#include "test_constants.hpp"
#include "tiny_column.hpp"

namespace granflow::mpm::test {

// A 3D scene of the frictional flume material on a grid of `size` from the origin, one stage,
// no walls, the terrain raster given (georeferenced at `origin`).
inline Scene terrain_scene(const std::vector<double>& size, double h, std::shared_ptr<const io::Raster> ground,
                    std::vector<double> origin, std::optional<double> mu) {
  Scene sc = test::tiny_column(ModelKind::Frictional);
  sc.material = flume_scene(0.04, 1e-4, ModelKind::Frictional, ShapeKind::Linear, 0.1).material;
  sc.dim = 3;
  sc.origin = {0.0, 0.0, 0.0};
  sc.size = size;
  sc.h = h;
  sc.gravity = {0.0, -kG, 0.0};
  sc.walls.clear();
  sc.tracks.clear();
  sc.runout_x.clear();
  sc.runout_y.clear();
  sc.output.times.clear();
  Stage s;
  s.name = "slide";
  s.duration = 0.3;
  sc.stages = {s};
  Terrain t;
  t.file = ground->file;
  t.origin = std::move(origin);
  t.mu = mu;
  t.raster = std::move(ground);
  sc.terrain = t;
  return sc;
}

}  // namespace granflow::mpm::test
