// One scene split into slabs along x (docs/mpm_slabs.md) on the CPU twin: 2 and 3 slabs equal
// the one-slab run bit for bit (the CI column in both shapes, the 3D CI slab, the CI flume's
// frictional base, the forces on an obstacle), with points crossing the borders; re-partitioning
// every few steps and restarting on another slab count change nothing; too many slabs for the
// grid, and the fp32 and mixed precisions (compiled for one slab only), are refused.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include <granflow/mpm/driver.hpp>
#include <granflow/mpm/runner.hpp>
#include <granflow/mpm/scene_file.hpp>

#include "one_thread.hpp"
#include "test_constants.hpp"
#include "tiny_column.hpp"

namespace granflow::mpm {
namespace {

struct Outcome {
  RunSummary s;
  Frame last;
  SlabReport report;
};

Outcome run_slabs(const Scene& sc, int slabs, long every = 0) {
  const SceneSetup su = make_setup(sc);
  SlabOptions o;
  o.slabs = slabs;
  o.every = every;
  auto r = make_cpu_runner(su, o);
  RunOptions opt;
  opt.progress = false;
  Outcome out;
  out.s = run(su, *r, opt);
  r->frame(out.last, true);
  out.report = r->slab_report();
  return out;
}

bool same_sums(const ForceSums& a, const ForceSums& b) {
  for (int d = 0; d < 3; ++d)
    if (a.impulse[d] != b.impulse[d] || a.moment[d] != b.moment[d]) return false;
  return a.normal == b.normal && a.tangential == b.tangential && a.max_force == b.max_force && a.steps == b.steps;
}

// Every particle field of the last frame, the run-out series and the force rows, bit for bit.
void expect_same(const Outcome& one, const Outcome& split, const std::string& what) {
  ASSERT_TRUE(one.s.ok) << what << ": " << one.s.message;
  ASSERT_TRUE(split.s.ok) << what << ": " << split.s.message;
  EXPECT_EQ(one.s.steps, split.s.steps) << what;
  EXPECT_EQ(one.last.x, split.last.x) << what;
  EXPECT_EQ(one.last.v, split.last.v) << what;
  EXPECT_EQ(one.last.p, split.last.p) << what;
  EXPECT_EQ(one.last.q, split.last.q) << what;
  EXPECT_EQ(one.last.e, split.last.e) << what;
  EXPECT_EQ(one.last.T, split.last.T) << what;
  EXPECT_EQ(one.last.eps_pd, split.last.eps_pd) << what;
  ASSERT_EQ(one.s.series.size(), split.s.series.size()) << what;
  for (size_t i = 0; i < one.s.series.size(); ++i) {
    EXPECT_EQ(one.s.series[i].m.runout, split.s.series[i].m.runout) << what << ", row " << i;
    EXPECT_EQ(one.s.series[i].m.height, split.s.series[i].m.height) << what << ", row " << i;
    EXPECT_EQ(one.s.series[i].m.kinetic_energy, split.s.series[i].m.kinetic_energy) << what << ", row " << i;
  }
  ASSERT_EQ(one.s.force_rows.size(), split.s.force_rows.size()) << what;
  for (size_t i = 0; i < one.s.force_rows.size(); ++i)
    EXPECT_TRUE(same_sums(one.s.force_rows[i].sums, split.s.force_rows[i].sums)) << what << ", force row " << i;
}

// The slabs' borders hold points on both sides at the end, and points crossed them.
void expect_split_used(const Outcome& split, int slabs, const std::string& what) {
  EXPECT_EQ(split.report.slabs, slabs) << what;
  ASSERT_EQ(split.report.borders.size(), static_cast<size_t>(slabs + 1)) << what;
  EXPECT_GT(split.report.migrated, 0) << what << ": no point crossed a border";
  EXPECT_GT(split.report.halo_nodes, 0) << what;
}

// A column `width` wide and `height` high behind the gate: a tall one collapses whole, so that
// the mass moves through every slab (Bui's 2:1 wide column keeps a static wedge at the back,
// where a border at its middle sees no point cross).
void make_tall(Scene& sc, double width, double height) {
  sc.size[1] = std::max(sc.size[1], height + 0.04);
  sc.bodies[0].box_max[0] = width;
  sc.bodies[0].box_max[1] = height;
  for (Stage& st : sc.stages)
    if (st.gate) st.gate->point[0] = width;
  sc.tracks.clear();
}

Scene tiny(ShapeKind shape, ModelKind model = ModelKind::PhaseTransition) {
  Scene sc = test::tiny_column(model, shape);
  make_tall(sc, 0.08, 0.20);
  sc.stages[1].duration = 0.15;
  return sc;
}

}  // namespace

TEST(MpmSlabs, CiColumnInTwoAndThreeSlabsEqualsOneBitwise) {
  for (ShapeKind shape : {ShapeKind::Linear, ShapeKind::QuadraticBSpline}) {
    const Scene sc = tiny(shape);
    const Outcome one = run_slabs(sc, 1);
    EXPECT_TRUE(one.report.borders.empty());  // not decomposed
    for (int n : {2, 3}) {
      const std::string what = std::string(shape == ShapeKind::Linear ? "linear" : "quadratic") + ", " +
                               std::to_string(n) + " slabs";
      const Outcome split = run_slabs(sc, n);
      expect_same(one, split, what);
      expect_split_used(split, n, what);
    }
  }
}

// Frictional-only model, the CI flume: a frictional base polyline (contact tables sliced per slab).
// 0.1 s of its 0.3 s of flow: points cross the borders by then (expect_split_used), and the
// whole flow took 84 s under the sanitizers (docs/reliability_ci.md).
TEST(MpmSlabs, CiFlumeWithFrictionalBaseEqualsOneBitwise) {
  Scene sc = load_scene(kScenes + "flume_ci_frictional.toml");
  sc.stages[1].duration = 0.1;
  sc.output.times.clear();
  const Outcome one = run_slabs(sc, 1);
  const Outcome split = run_slabs(sc, 3);
  expect_same(one, split, "flume, 3 slabs");
  expect_split_used(split, 3, "flume, 3 slabs");
}

TEST(MpmSlabs, ThreeDCiSlabInTwoAndThreeSlabsEqualsOneBitwise) {
  Scene sc = load_scene(kScenes + "column_collapse_3d_ci.toml");
  make_tall(sc, 0.08, 0.20);
  sc.stages[1].duration = 0.1;
  const Outcome one = run_slabs(sc, 1);
  for (int n : {2, 3}) {
    const Outcome split = run_slabs(sc, n);
    expect_same(one, split, "3D, " + std::to_string(n) + " slabs");
    expect_split_used(split, n, "3D, " + std::to_string(n) + " slabs");
  }
}

// The forces on an obstacle and on the walls and base: each slab measures the probes of its
// columns, the sums run in the set-up's probe order.
TEST(MpmSlabs, ForcesOnAnObstacleEqualOneSlabBitwise) {
  Scene sc = load_scene(kScenes + "column_obstacle_ci.toml");
  make_tall(sc, 0.12, 0.13);
  sc.stages[0].duration = 0.02;
  sc.stages[1].duration = 0.12;
  const Outcome one = run_slabs(sc, 1);
  ASSERT_FALSE(one.s.force_rows.empty());
  const Outcome split = run_slabs(sc, 2);
  expect_same(one, split, "obstacle, 2 slabs");
  expect_split_used(split, 2, "obstacle, 2 slabs");
  double impulse = 0;
  for (const ForceRow& row : one.s.force_rows) impulse += std::fabs(row.sums.impulse[0]);
  EXPECT_GT(impulse, 0);  // the forces compared are not all zero
}

// A re-partition every 7 steps moves the borders with the collapsing column and changes nothing.
TEST(MpmSlabs, ForcedRepartitioningEveryFewStepsChangesNothing) {
  const Scene sc = tiny(ShapeKind::QuadraticBSpline);
  const Outcome one = run_slabs(sc, 1);
  const Outcome split = run_slabs(sc, 3, 7);
  expect_same(one, split, "3 slabs, re-partitioned every 7 steps");
  EXPECT_GT(split.report.checks, 100);
  EXPECT_GT(split.report.repartitions, 0) << "the borders never moved";
}

// A state taken from one slab continues on three (a checkpoint restarted on another GPU count).
TEST(MpmSlabs, StateMovesBetweenSlabCounts) {
  const Scene sc = tiny(ShapeKind::Linear);
  const SceneSetup su = make_setup(sc);
  auto one = make_cpu_runner(su);
  SlabOptions o;
  o.slabs = 3;
  auto three = make_cpu_runner(su, o);
  for (Runner* r : {one.get(), three.get()}) r->set_stage(1, 0.0, sc.flip);
  ASSERT_TRUE(one->advance(150, sc.dt).ok);
  HostParticles mid;
  one->download(mid);
  three->upload(mid);
  ASSERT_TRUE(one->advance(150, sc.dt).ok);
  ASSERT_TRUE(three->advance(150, sc.dt).ok);
  HostParticles a, b;
  one->download(a);
  three->download(b);
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.v, b.v);
  EXPECT_EQ(a.sig, b.sig);
  EXPECT_EQ(a.e, b.e);
  EXPECT_EQ(a.s, b.s);
}

TEST(MpmSlabs, MoreSlabsThanTheGridHoldsAreRefused) {
  const SceneSetup su = make_setup(tiny(ShapeKind::QuadraticBSpline));
  SlabOptions o;
  o.slabs = su.nodes[0] / 3 + 1;
  try {
    make_cpu_runner(su, o);
    FAIL() << "accepted " << o.slabs << " slabs on " << su.nodes[0] << " columns";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("columns along x"), std::string::npos) << e.what();
  }
  o.slabs = su.nodes[0] / 3;
  EXPECT_NO_THROW(make_cpu_runner(su, o));
  Scene fp32 = tiny(ShapeKind::QuadraticBSpline);
  fp32.precision = Precision::FP32;
  o.slabs = 2;
  try {
    make_cpu_runner(make_setup(fp32), o);
    FAIL() << "split an fp32 scene";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("fp64 scenes only (solver.precision = fp32)"), std::string::npos) << e.what();
  }
  Scene two = tiny(ShapeKind::QuadraticBSpline);
  Material b = two.material;
  b.label = "b";
  two.material.label = "a";
  two.other_materials = {b};
  try {
    make_cpu_runner(make_setup(two), o);
    FAIL() << "split a scene of two materials";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("several materials are not split yet (this one has 2)"), std::string::npos)
        << e.what();
  }
}

// The slab report against a hand-counted case: a block translating at 1 m/s in zero gravity
// across the border that splits it in two, borders held (no re-partition): every point that
// starts left of the border ends right of it, so `migrated` is their count, and at the end
// one slab holds all points, the largest imbalance 2.
TEST(MpmSlabs, ReportCountsTheMigrantsOfATranslatingBlock) {
  Scene sc = test::tiny_column(ModelKind::Frictional);
  test::one_open_stage(sc, "move", 0.1);
  sc.walls.push_back({1, false, 0.0, false, "wall[0].side"});  // a floor the block never meets: a split needs a boundary
  sc.gravity = {0.0, 0.0};
  sc.bodies[0].box_min = {0.1, 0.04};
  sc.bodies[0].box_max = {0.2, 0.08};
  SceneSetup su = make_setup(sc);
  const long n = su.particles.n;
  for (long i = 0; i < n; ++i) su.particles.v[i] = 1.0;
  SlabOptions o;
  o.slabs = 2;
  o.imbalance = 1e9;  // the start's borders stay
  auto r = make_cpu_runner(su, o);
  const std::vector<int> start = r->slab_report().borders;
  ASSERT_EQ(start.size(), 3u);
  auto column = [&](double x) { return static_cast<int>(std::floor((x - su.origin[0]) / sc.h)); };  // linear hats
  long left = 0;
  for (long i = 0; i < n; ++i) left += column(su.particles.x[i]) < start[1];
  ASSERT_GT(left, n / 4);
  ASSERT_LT(left, 3 * n / 4);
  RunOptions opt;
  opt.progress = false;
  const RunSummary s = run(su, *r, opt);
  ASSERT_TRUE(s.ok) << s.message;
  Frame f;
  r->frame(f, false);
  for (long i = 0; i < n; ++i) ASSERT_GE(column(f.x[i]), start[1]) << "point " << i << " did not cross";
  const SlabReport rep = r->slab_report();
  EXPECT_EQ(rep.borders, start);
  EXPECT_EQ(rep.repartitions, 0);
  EXPECT_EQ(rep.migrated, left);
  EXPECT_EQ(rep.max_imbalance, 2.0);
}

}  // namespace granflow::mpm
