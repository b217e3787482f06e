// The CI column on a 20 mm grid (200 points) with a larger step: the MPM tests' small scene.
#pragma once

#include <granflow/mpm/scene.hpp>

namespace granflow::mpm::test {

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

}  // namespace granflow::mpm::test
