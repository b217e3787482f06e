// The 3D terrain scenes of the terrain tests (test_mpm_terrain.cpp, test_mpm_terrain_contact.cpp).
#pragma once

#include <functional>
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

// A raster in memory: elevation z(easting, northing) at the cell centres.
inline std::shared_ptr<const io::Raster> raster(double west, double south, double cell, long ncols, long nrows,
                                         const std::function<double(double, double)>& z) {
  auto r = std::make_shared<io::Raster>();
  r->file = "memory";
  r->ncols = ncols;
  r->nrows = nrows;
  r->west = west;
  r->south = south;
  r->cellsize = cell;
  for (long row = 0; row < nrows; ++row)
    for (long col = 0; col < ncols; ++col) r->values.push_back(z(r->centre_east(col), r->centre_north(row)));
  return r;
}

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
  one_open_stage(sc, "slide", 0.3);
  Terrain t;
  t.file = ground->file;
  t.origin = std::move(origin);
  t.mu = mu;
  t.raster = std::move(ground);
  sc.terrain = t;
  return sc;
}

}  // namespace granflow::mpm::test
