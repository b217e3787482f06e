// Several materials in one scene (issue 34) on the CPU twin: blocks of two materials on one grid
// equal their single-material runs bit for bit (2D, 3D, and without boundary code), an ensemble
// of such scenes equals its members' single runs, and a block on a slope slides on a weak layer
// and stays on a strong one.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <granflow/mpm/driver.hpp>
#include <granflow/mpm/ensemble.hpp>
#include <granflow/mpm/kernels.hpp>
#include <granflow/mpm/runner.hpp>

#include "one_thread.hpp"
#include "test_constants.hpp"

namespace granflow::mpm {
namespace {

Body box(double x0, double y0, double x1, double y1, int material) {
  Body b;
  b.box_min = {x0, y0};
  b.box_max = {x1, y1};
  b.material = material;
  return b;
}

// The CI column's grid, walls and step, one stage of 0.04 s, no gate. Material "a" and
// material "b" (phi_c 30 deg, looser, heavier grains) give points of the same mass
// (rho_p / (1 + e0) = 1000 exactly), so the light-node thresholds of a run (from the smallest
// mass) do not depend on which blocks it holds.
Scene two_block_base(ModelKind model, ShapeKind shape) {
  Scene sc = small_column_scene(model, shape);
  Stage st;
  st.name = "flow";
  st.duration = 0.04;
  sc.stages = {st};
  sc.output.times.clear();
  sc.tracks.clear();
  sc.material.label = "a";
  sc.material.e0 = 0.75;
  sc.material.params.c.rho_p = 1750;
  Material b = sc.material;
  b.label = "b";
  b.e0 = 0.875;
  b.params.c.rho_p = 1875;
  b.params.f.phi_c = 30 * kDeg;
  sc.other_materials = {b};
  return sc;
}

// Blocks A (material a) and B (material b), ten cells apart: no stencil reaches both.
Scene two_blocks(ModelKind model, ShapeKind shape) {
  Scene sc = two_block_base(model, shape);
  sc.bodies = {box(0.02, 0.0, 0.10, 0.06, 0), box(0.30, 0.0, 0.38, 0.06, 1)};
  return sc;
}

// The blocks in 3D: 40 x 8 x 2 cm between free-slip side walls (z), 0.01 s; blocks of
// 6 x 4 x 2 cm, 18 cells apart.
Scene two_blocks_3d(ModelKind model, ShapeKind shape) {
  Scene sc = two_block_base(model, shape);
  sc.dim = 3;
  sc.origin = {0.0, 0.0, 0.0};
  sc.size = {0.40, 0.08, 0.02};
  sc.gravity = {0.0, -9.81, 0.0};
  sc.walls[1].position = 0.40;
  sc.walls.push_back({2, false, 0.0, false, "wall[3].side"});
  sc.walls.push_back({2, true, 0.02, false, "wall[4].side"});
  sc.runout_x = {0.0, 0.40};
  sc.stages[0].duration = 0.01;
  Body a = box(0.02, 0.0, 0.08, 0.04, 0), b = box(0.26, 0.0, 0.32, 0.04, 1);
  for (Body* p : {&a, &b}) {
    p->box_min.push_back(0.0);
    p->box_max.push_back(0.02);
  }
  sc.bodies = {a, b};
  return sc;
}

// The blocks without a wall, a base or a gate: in free fall from 5 cm above the grid's bottom.
Scene two_falling_blocks(ModelKind model, ShapeKind shape) {
  Scene sc = two_block_base(model, shape);
  sc.walls.clear();
  sc.bodies = {box(0.02, 0.05, 0.10, 0.11, 0), box(0.30, 0.05, 0.38, 0.11, 1)};
  return sc;
}

// Block `which` of `two` alone, as a scene of its one material.
Scene one_block(const Scene& two, int which) {
  Scene sc = two;
  sc.material = two.material_at(which);
  sc.material.label.clear();
  sc.other_materials.clear();
  sc.bodies = {two.bodies[which]};
  sc.bodies[0].material = 0;
  return sc;
}

HostParticles run_steps(const SceneSetup& su, long steps) {
  auto r = make_cpu_runner(su);
  const StepResult res = r->advance(steps, su.scene.dt);
  EXPECT_TRUE(res.ok) << "particle " << res.particle << ": " << status_field(res.status);
  HostParticles out;
  r->download(out);
  return out;
}

// Points [from, from + n) of `all` against `one` (n points), bitwise.
void expect_same_points(const HostParticles& all, long from, const HostParticles& one, const std::string& what) {
  ASSERT_EQ(all.dim, one.dim);
  const long n = one.n;
  auto cmp = [&](const std::vector<double>& a, const std::vector<double>& b, int comps, const char* field) {
    for (int c = 0; c < comps; ++c)
      EXPECT_EQ(0, std::memcmp(a.data() + c * all.n + from, b.data() + c * n, n * sizeof(double)))
          << what << ": " << field << " (component " << c << ") differs from the single-material run";
  };
  cmp(all.x, one.x, all.dim, "position");
  cmp(all.v, one.v, all.dim, "velocity");
  cmp(all.sig, one.sig, 6, "stress");
  cmp(all.eps, one.eps, 1, "plastic strain");
  cmp(all.e, one.e, 1, "void ratio");
  cmp(all.s, one.s, 1, "sqrt T");
}

void expect_blocks_equal_single_runs(const Scene& scene) {
  const SceneSetup two = make_setup(scene);
  ASSERT_EQ(two.point_material.size(), static_cast<size_t>(two.particles.n));
  const SceneSetup a = make_setup(one_block(scene, 0)), b = make_setup(one_block(scene, 1));
  ASSERT_TRUE(a.point_material.empty());  // one material: today's kernels
  ASSERT_EQ(a.particles.n + b.particles.n, two.particles.n);
  const long steps = std::lround(two.scene.stages[0].duration / two.scene.dt);
  const HostParticles all = run_steps(two, steps);
  const HostParticles pa = run_steps(a, steps), pb = run_steps(b, steps);
  expect_same_points(all, 0, pa, "block A");
  expect_same_points(all, a.particles.n, pb, "block B");
  // the materials differ where it shows: the blocks' states are not the same
  EXPECT_NE(0, std::memcmp(pa.e.data(), pb.e.data(), std::min(pa.n, pb.n) * sizeof(double)));
}

TEST(MpmMaterials, TwoBlocksEqualTheirSingleMaterialRunsBitForBit) {
  expect_blocks_equal_single_runs(two_blocks(ModelKind::PhaseTransition, ShapeKind::Linear));
}

TEST(MpmMaterials, FrictionalQuadraticBlocksEqualTheirSingleMaterialRuns) {
  expect_blocks_equal_single_runs(two_blocks(ModelKind::Frictional, ShapeKind::QuadraticBSpline));
}

// 3D (the fp64 kMembers instantiations of 3D): 384 points per block, 200 steps.
TEST(MpmMaterials, ThreeDBlocksEqualTheirSingleMaterialRunsBitForBit) {
  expect_blocks_equal_single_runs(two_blocks_3d(ModelKind::Frictional, ShapeKind::QuadraticBSpline));
  expect_blocks_equal_single_runs(two_blocks_3d(ModelKind::PhaseTransition, ShapeKind::Linear));
}

// No boundary code in the scene: the several-material run takes the instantiation with it
// (masks that hold no node), its single runs the one without.
TEST(MpmMaterials, FallingBlocksWithoutWallsEqualTheirSingleMaterialRuns) {
  const Scene sc = two_falling_blocks(ModelKind::Frictional, ShapeKind::QuadraticBSpline);
  const SceneSetup su = make_setup(sc);
  EXPECT_FALSE(su.has_boundary);
  ASSERT_EQ(su.stage_masks.size(), 1u);
  EXPECT_EQ(su.stage_masks[0], std::vector<std::uint8_t>(su.n_nodes, 0));  // no node held, no contact table
  expect_blocks_equal_single_runs(sc);
}

// Per-material series (materials.csv): each material's run-out, height and energies are those
// of its single-material run, bit for bit (the twin keeps the points in their set-up order).
TEST(MpmMaterials, PerMaterialSeriesAreThoseOfTheSingleMaterialRuns) {
  Scene sc = two_blocks(ModelKind::Frictional, ShapeKind::Linear);
  sc.stages[0].duration = 0.01;  // ten samples
  const auto dir = std::filesystem::temp_directory_path() / "granflow_materials_series";
  std::filesystem::remove_all(dir);
  auto run_scene = [&](const Scene& s, const std::string& out) {
    const SceneSetup su = make_setup(s);
    auto r = make_cpu_runner(su);
    RunOptions opt;
    opt.progress = false;
    opt.out_dir = out;
    return run(su, *r, opt);
  };
  const RunSummary two = run_scene(sc, dir.string());
  ASSERT_TRUE(two.ok) << two.message;
  for (int k = 0; k < 2; ++k) {
    const RunSummary one = run_scene(one_block(sc, k), "");
    ASSERT_EQ(one.series.size(), two.series.size());
    ASSERT_EQ(two.material_series.size(), 2 * two.series.size());
    EXPECT_TRUE(one.material_series.empty());
    for (size_t i = 0; i < one.series.size(); ++i) {
      const Measures &a = two.material_series[2 * i + k], &b = one.series[i].m;
      EXPECT_EQ(a.runout, b.runout) << "material " << k << ", sample " << i;
      EXPECT_EQ(a.height, b.height);
      EXPECT_EQ(a.kinetic_energy, b.kinetic_energy);
      EXPECT_EQ(a.max_speed, b.max_speed);
    }
  }
  std::ifstream in(dir / "materials.csv");
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "t,t_flow,stage,material,runout,height,max_speed,kinetic_energy,mean_T,max_T");
  long rows = 0, of_b = 0;
  while (std::getline(in, line)) {
    ++rows;
    of_b += line.find(",b,") != std::string::npos;
  }
  EXPECT_EQ(rows, 2 * static_cast<long>(two.series.size()));
  EXPECT_EQ(of_b, static_cast<long>(two.series.size()));
  std::filesystem::remove_all(dir);
}

// 3D in float storage (fp32 and mixed): the several-material kernels equal the single-material
// ones bit for bit there too.
TEST(MpmMaterials, ThreeDBlocksInFloatPrecisionsEqualTheirSingleMaterialRuns) {
  for (Precision p : {Precision::FP32, Precision::Mixed}) {
    Scene sc = two_blocks_3d(ModelKind::Frictional, ShapeKind::Linear);
    sc.precision = p;
    expect_blocks_equal_single_runs(sc);
  }
}

// An ensemble of two-material scenes: member k's values at k * materials + material.
TEST(MpmMaterials, EnsembleOfTwoMaterialScenesEqualsItsSingleRuns) {
  std::vector<Scene> scenes(2, two_blocks(ModelKind::Frictional, ShapeKind::Linear));
  scenes[1].other_materials[0].params.f.phi_c = 25 * kDeg;  // member 1: a weaker b
  std::vector<SceneSetup> ms;
  for (const Scene& s : scenes) ms.push_back(make_setup(s));
  const SceneSetup su = make_ensemble_setup(ms);
  ASSERT_EQ(su.member_materials.size(), 4u);
  const long steps = std::lround(su.scene.stages[0].duration / su.scene.dt);
  const HostParticles all = run_steps(su, steps);
  for (int k = 0; k < 2; ++k) expect_same_points(all, k * ms[0].particles.n, run_steps(ms[k], steps), "member " + std::to_string(k));
}

// A 280 x 8 cm block on a 25 deg slope (gravity tilted over a no-slip floor, 20 mm grid, its
// upslope end at a free-slip wall): a strong layer (phi_c 35 deg) over a layer two cells thick
// of phi_c `weak_deg`, at rest at t = 0 (the infinite slope's stresses), 0.2 s. Both layers
// harden faster than the column's sand (k_p 0.001), so that the strong one mobilizes its
// friction with little plastic strain.
struct SlopeResult {
  double weak_share = 0;   // of the plastic shear strain (eps_pd gained) of the whole block
  double inner_share = 0;  // ... of its part 0.2 m or more from either end
  double slide = 0;        // mean downslope displacement of the strong layer's inner part [m]
};

SlopeResult slope(double weak_deg) {
  constexpr double kLength = 2.8, kWeakTop = 0.04, kTop = 0.08, kEnd = 0.2, kTaper = 0.14;
  Scene sc = small_column_scene(ModelKind::Frictional);
  sc.h = 0.02;
  sc.dt = 1e-4;
  sc.size = {3.0, 0.24};
  sc.walls[1].position = 3.0;
  const double g = 9.81, tilt = 25 * kDeg;
  sc.gravity = {g * std::sin(tilt), -g * std::cos(tilt)};
  Stage st;
  st.name = "slide";
  st.duration = 0.2;
  sc.stages = {st};
  sc.output.times.clear();
  sc.tracks.clear();
  sc.material.label = "strong";
  sc.material.params.f.phi_c = 35 * kDeg;
  sc.material.params.f.k_p = 0.001;
  Material weak = sc.material;
  weak.label = "weak";
  weak.params.f.phi_c = weak_deg * kDeg;
  sc.other_materials = {weak};
  // the strong layer's downslope end tapers over kTaper to the weak layer's top (16 deg to the
  // slope): a face perpendicular to the slope, cohesionless, slumps whatever lies under it
  Body strong;
  strong.poly_x = {0.0, kLength, kLength - kTaper, 0.0};
  strong.poly_y = {kWeakTop, kWeakTop, kTop, kTop};
  strong.material = 0;
  sc.bodies = {box(0.0, 0.0, kLength, kWeakTop, 1), strong};
  SceneSetup su = make_setup(sc);
  // At rest on the slope: sigma_yy = -rho g cos(25) d and, in the strong layer, sigma_xy =
  // rho g sin(25) d at depth d (isotropic otherwise); none in the weak layer, which cannot
  // carry it. Each point on its yield surface (initial_plastic_strain), as make_setup does.
  HostParticles& hp = su.particles;
  const long n = hp.n;
  for (long i = 0; i < n; ++i) {
    const int mi = su.point_material[i];
    const Material& m = sc.material_at(mi);
    const double x = hp.x[i], top = x < kLength - kTaper ? kTop : kTop - (kTop - kWeakTop) * (x - (kLength - kTaper)) / kTaper;
    const double d = std::max(top - hp.x[n + i], 0.0), rho = m.params.c.rho_p / (1 + m.e0);
    Mat3<double> s = Mat3<double>::Zero();
    s(0, 0) = s(1, 1) = s(2, 2) = -rho * g * std::cos(tilt) * d;
    if (mi == 0) s(0, 1) = s(1, 0) = rho * g * std::sin(tilt) * d;
    const double v6[6] = {s(0, 0), s(1, 1), s(2, 2), 0, 0, s(0, 1)};
    for (int c = 0; c < 6; ++c) hp.sig[c * n + i] = hp.sigf[c * n + i] = v6[c];
    hp.eps[i] = initial_plastic_strain<LodeShape::SmoothMohrCoulomb>(m.params.f, s, m.e0);
    EXPECT_GE(hp.eps[i], 0.0) << "point " << i << " starts outside its yield surface";
  }
  auto r = make_cpu_runner(su);
  Frame f0, f1;
  r->frame(f0, true);
  const StepResult res = r->advance(std::lround(st.duration / sc.dt), sc.dt);
  EXPECT_TRUE(res.ok) << "particle " << res.particle << ": " << status_field(res.status);
  r->frame(f1, true);
  double all = 0, lower = 0, inner = 0, inner_lower = 0, dx = 0;
  long upper = 0;
  for (long i = 0; i < n; ++i) {
    const double d = f1.eps_pd[i] - f0.eps_pd[i];
    const bool weak_point = su.point_material[i] == 1, inside = f0.x[i] > kEnd && f0.x[i] < kLength - kEnd;
    all += d;
    lower += weak_point ? d : 0;
    if (!inside) continue;
    inner += d;
    inner_lower += weak_point ? d : 0;
    if (!weak_point) {
      dx += f1.x[i] - f0.x[i];
      ++upper;
    }
  }
  return {lower / all, inner_lower / inner, dx / double(upper)};
}

// The ends of a cohesionless block yield whatever lies under it, so their share falls with the
// block's length: 93.5 % of the plastic shear strain lies in the weak layer over the whole block,
// 96.6 % away from the ends (a 1.4 m block: 88.1 and 93.1 %).
TEST(MpmMaterials, LayeredBlockSlidesOnItsWeakLayerAndStaysOnAStrongOne) {
  const SlopeResult weak = slope(20), strong = slope(35);
  std::printf("slope 25 deg, weak layer phi_c 20: %.3f of the plastic shear strain in the weak layer (%.3f away from "
              "the ends), slide %.4f m; both 35: slide %.5f m\n",
              weak.weak_share, weak.inner_share, weak.slide, strong.slide);
  EXPECT_GE(weak.inner_share, 0.9) << "plastic shear strain in the weak layer, away from the block's ends";
  EXPECT_GE(weak.weak_share, 0.9) << "plastic shear strain in the weak layer, whole block";
  EXPECT_GT(weak.slide, 0.01) << "mean downslope displacement of the strong layer [m]";
  EXPECT_LT(std::fabs(strong.slide), 0.002) << "both layers strong";
  EXPECT_GT(weak.slide, 10 * std::fabs(strong.slide));
}

}  // namespace
}  // namespace granflow::mpm

namespace granflow::mpm {

// The stable step of a scene of several materials is the smallest over its materials, whichever
// comes first, and a fixed time.dt above it is refused naming time.dt. Material b is material a
// nine times stiffer: its P-wave speed is 3 times a's (moduli scale with K0), its limit a third.
TEST(MpmMaterials, StableStepIsTheSmallestOverTheMaterials) {
  Scene sc = two_blocks(ModelKind::Frictional, ShapeKind::Linear);
  Material b = sc.material;
  b.label = "b";
  b.params.f.K0 *= 9;
  sc.other_materials = {b};
  sc.adaptive = false;
  sc.dt = 1e-7;
  const double limit_a = make_setup(one_block(sc, 0)).dt_estimate, limit_b = make_setup(one_block(sc, 1)).dt_estimate;
  EXPECT_NEAR(limit_b, limit_a / 3, 1e-12 * limit_a);
  Scene swapped = sc;
  swapped.material = b;
  swapped.material.label = "a";  // labels aside, b first
  swapped.other_materials = {sc.material};
  swapped.other_materials[0].label = "b";
  for (Body& body : swapped.bodies) body.material = 1 - body.material;
  for (const Scene* s : {&sc, &swapped}) {
    EXPECT_EQ(make_setup(*s).dt_estimate, limit_b) << (s == &sc ? "stiff material second" : "stiff material first");
    Scene fixed = *s;
    fixed.dt = 2 * limit_b;  // below a's limit, above b's
    try {
      make_setup(fixed);
      ADD_FAILURE() << "accepted time.dt = " << fixed.dt << " s above the stiff material's limit " << limit_b;
    } catch (const SceneError& e) {
      EXPECT_EQ(e.key(), "time.dt") << e.what();
    }
    fixed.dt = 0.9 * limit_b;
    EXPECT_NO_THROW(make_setup(fixed));
  }
}

}  // namespace granflow::mpm
