// The 3D column collapse (mpm/scenes/column_collapse_3d*.toml): the CI slab between free-slip
// side walls reproduces the plane-strain column of the same size, and the GPU benchmark scene
// describes the same set-up at 1 mm.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <granflow/mpm/driver.hpp>

#include <granflow/mpm/scene_file.hpp>
#include "one_thread.hpp"
#include "tiny_column.hpp"
#include "test_constants.hpp"

using namespace granflow;
using namespace granflow::mpm;

namespace {

struct SlabRun {
  RunSummary s;
  Frame initial, last;
};

SlabRun run_scene(const Scene& sc) {
  const SceneSetup su = make_setup(sc);
  auto r = make_cpu_runner(su);
  SlabRun out;
  r->frame(out.initial, false);
  RunOptions opt;
  opt.progress = false;
  out.s = run(su, *r, opt);
  r->frame(out.last, false);
  return out;
}

// The 2D column of the same size: the CI column on a 20 mm grid (the tiny column of the tests).
Scene plane_strain_column(ShapeKind shape) { return test::tiny_column(ModelKind::PhaseTransition, shape); }

}  // namespace

// The slab (10 x 5 x 2 cells, 800 points, quadratic B-splines) after consolidation and 0.3 s of
// collapse: it runs out after the gate opens, stays plane (z-velocities and z-displacements at
// round-off amplified by the flow: below 1 % of the speed and 1e-3 of the grid spacing), and ends within
// 1 % of the 2D column in run-out, height and base stress. In fp32 too.
TEST(Mpm3d, CiSlabReproducesThePlaneStrainColumn) {
  Scene sc = mpm::load_scene(kScenes + "column_collapse_3d_ci.toml");
  ASSERT_EQ(sc.dim, 3);
  const SlabRun r3 = run_scene(sc);
  const SlabRun r2 = run_scene(plane_strain_column(sc.shape));
  ASSERT_TRUE(r3.s.ok) << r3.s.message;
  ASSERT_TRUE(r2.s.ok) << r2.s.message;
  const long n = r3.last.n;
  EXPECT_EQ(n, 800);

  // run-out grows once the gate is open, and not before
  double t_release = sc.stages[0].duration, before = 0, at_release = 0;
  for (const auto& row : r3.s.series) {
    if (row.t <= t_release + 1e-9) {
      before = std::max(before, row.m.runout);
      at_release = row.m.runout;
    }
  }
  EXPECT_NEAR(before, 0.2, 0.005);  // the gate held the column
  double prev = at_release;
  for (const auto& row : r3.s.series)
    if (row.t > t_release) {
      EXPECT_GE(row.m.runout, prev - 1e-3) << "t = " << row.t;  // grows (to a bin of run-out noise)
      prev = std::max(prev, row.m.runout);
    }
  EXPECT_GT(r3.s.final.runout, at_release + 0.04);

  // plane strain: z-velocities and z-displacements stay small
  double vmax = 0, vz = 0, dz = 0;
  for (long i = 0; i < n; ++i) {
    double v2 = 0;
    for (int d = 0; d < 3; ++d) v2 += r3.last.v[d * n + i] * r3.last.v[d * n + i];
    vmax = std::max(vmax, std::sqrt(v2));
    vz = std::max(vz, std::fabs(r3.last.v[2 * n + i]));
    dz = std::max(dz, std::fabs(r3.last.x[2 * n + i] - r3.initial.x[2 * n + i]));
  }
  std::printf("3D CI slab: run-out %.5f m (2D %.5f), height %.5f m (2D %.5f), base sigma_v %.1f Pa (2D %.1f); "
              "max |v_z| %.2e m/s of max |v| %.3f m/s, max |dz| %.2e m; wall %.2f s (2D %.2f s)\n",
              r3.s.final.runout, r2.s.final.runout, r3.s.final.height, r2.s.final.height,
              r3.s.consolidation.base_sigma_v, r2.s.consolidation.base_sigma_v, vz, vmax, dz, r3.s.wall_s,
              r2.s.wall_s);
  EXPECT_LT(vz, 0.01 * vmax);
  EXPECT_LT(dz, 1e-3 * sc.h);  // 20 um; measured 3-5 um

  // the 2D column of the same size
  EXPECT_NEAR(r3.s.final.runout / r2.s.final.runout, 1.0, 0.01);
  EXPECT_NEAR(r3.s.final.height / r2.s.final.height, 1.0, 0.01);
  ASSERT_TRUE(r3.s.consolidation.done);
  EXPECT_NEAR(r3.s.consolidation.base_sigma_v / r2.s.consolidation.base_sigma_v, 1.0, 0.01);

  // fp32 (3D float instantiation of the CPU twin): within 1 % of fp64
  sc.precision = Precision::FP32;
  const SlabRun f = run_scene(sc);
  ASSERT_TRUE(f.s.ok) << f.s.message;
  std::printf("3D CI slab fp32: run-out %.5f m, height %.5f m; wall %.2f s\n", f.s.final.runout, f.s.final.height,
              f.s.wall_s);
  EXPECT_NEAR(f.s.final.runout / r3.s.final.runout, 1.0, 0.01);
  EXPECT_NEAR(f.s.final.height / r3.s.final.height, 1.0, 0.01);
}

// The GPU benchmark scene is the CI slab's set-up at 1 mm and 50 mm width: 8e6 points (not set up
// here: 2 GB), same material, walls, gate and stages as the 2D paper scene.
TEST(Mpm3d, BenchmarkSceneIsThePaperColumnAsASlab) {
  const Scene big = mpm::load_scene(kScenes + "column_collapse_3d.toml");
  const Scene ci = mpm::load_scene(kScenes + "column_collapse_3d_ci.toml");
  const Scene col = mpm::load_scene(kScenes + "column_collapse.toml");
  ASSERT_EQ(big.dim, 3);
  EXPECT_DOUBLE_EQ(big.h, 0.001);
  EXPECT_EQ(big.ppc_axis, 2);
  EXPECT_EQ(big.shape, ShapeKind::QuadraticBSpline);
  EXPECT_EQ(ci.shape, big.shape);
  EXPECT_DOUBLE_EQ(big.dt, col.dt);
  ASSERT_EQ(big.bodies.size(), 1u);
  long points = 1;
  for (int d = 0; d < 3; ++d)
    points *= std::lround((big.bodies[0].box_max[d] - big.bodies[0].box_min[d]) / (big.h / big.ppc_axis));
  EXPECT_EQ(points, 8000000L);
  EXPECT_DOUBLE_EQ(big.bodies[0].box_max[2], big.size[2]);  // the slab fills the width
  for (const Scene* s : {&big, &ci}) {
    EXPECT_EQ(s->material.model, col.material.model);
    EXPECT_DOUBLE_EQ(s->material.e0, col.material.e0);
    EXPECT_DOUBLE_EQ(s->material.params.f.phi_c, col.material.params.f.phi_c);
    EXPECT_DOUBLE_EQ(s->material.params.c.rho_p, col.material.params.c.rho_p);
    ASSERT_EQ(s->walls.size(), 5u);
    for (size_t k = 0; k < 3; ++k) {  // x-, x+, y- as in 2D
      EXPECT_EQ(s->walls[k].axis, col.walls[k].axis);
      EXPECT_EQ(s->walls[k].at_max, col.walls[k].at_max);
      EXPECT_EQ(s->walls[k].no_slip, col.walls[k].no_slip);
    }
    for (size_t k = 3; k < 5; ++k) {  // free-slip side walls at z = 0 and z = W
      EXPECT_EQ(s->walls[k].axis, 2);
      EXPECT_FALSE(s->walls[k].no_slip);
    }
    ASSERT_EQ(s->stages.size(), 2u);
    ASSERT_TRUE(s->stages[0].gate.has_value());
    EXPECT_EQ(s->stages[0].gate->normal, (std::vector<double>{1.0, 0.0, 0.0}));
    EXPECT_DOUBLE_EQ(s->stages[0].damping, col.stages[0].damping);
  }
  EXPECT_DOUBLE_EQ(big.stages[0].duration, col.stages[0].duration);
  EXPECT_DOUBLE_EQ(big.stages[1].duration, col.stages[1].duration);
}
