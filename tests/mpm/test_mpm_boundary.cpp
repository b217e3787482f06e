// Boundaries of parameter studies (boundary.hpp): Coulomb friction at walls and at the base
// polyline, and a gate lifted at a finite speed. CPU twin, small scenes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdint>
#include <new>
#include <optional>
#include <utility>
#include <vector>

#include <granflow/mpm/driver.hpp>
#include <granflow/mpm/kernels.hpp>

#include "one_thread.hpp"
#include "sampled_run.hpp"
#include "tiny_column.hpp"
#include "test_constants.hpp"

using namespace granflow;
using namespace granflow::mpm;
using namespace granflow::mpm::test;

namespace {

// Frictional material of the flume set (phi_c = 38 deg: a base friction up to ~0.7 slides the
// block rather than shearing it) on a 20 mm grid, FLIP with the PIC rate of the paper scenes.
Scene block_base_scene(int dim) {
  Scene sc = test::tiny_column(ModelKind::Frictional);
  sc.material = flume_scene(0.04, 1e-4, ModelKind::Frictional, ShapeKind::Linear, 0.1).material;
  sc.dim = dim;
  test::one_open_stage(sc, "slide", 0.3);
  return sc;
}

// A block lying on the floor y = 0 with gravity tilted by theta towards +x: the floor is an
// incline of angle theta. The floor is no-slip, free-slip or frictional (mu).
Scene incline_scene(int dim, double theta, std::optional<double> mu, bool no_slip = false) {
  Scene sc = block_base_scene(dim);
  sc.origin.assign(dim, 0.0);
  sc.size = {0.8, 0.12};
  Body b;
  b.box_min = {0.1, 0.0};
  b.box_max = {0.5, 0.06};
  if (dim == 3) {  // shorter and thinner: 480 points
    b.box_max[0] = 0.3;
    sc.size.push_back(0.04);
    b.box_min.push_back(0.0);
    b.box_max.push_back(0.04);
  }
  sc.bodies = {b};
  sc.gravity.assign(dim, 0.0);
  sc.gravity[0] = kG * std::sin(theta);
  sc.gravity[1] = -kG * std::cos(theta);
  Wall floor{1, false, 0.0, no_slip, "wall[0].side"};
  floor.mu = mu;
  sc.walls = {floor};
  if (dim == 3) {  // the slab between free-slip walls in z
    sc.walls.push_back({2, false, 0.0, false, "wall[1].side"});
    sc.walls.push_back({2, true, 0.04, false, "wall[2].side"});
  }
  return sc;
}

// Least-squares slope of v(t) over t >= t0.
double slope(const Motion& mo, double t0) {
  double st = 0, sv = 0, stt = 0, stv = 0, n = 0;
  for (size_t k = 0; k < mo.t.size(); ++k) {
    if (mo.t[k] < t0) continue;
    st += mo.t[k];
    sv += mo.v[k];
    stt += mo.t[k] * mo.t[k];
    stv += mo.t[k] * mo.v[k];
    n += 1;
  }
  return (n * stv - st * sv) / (n * stt - st * st);
}

// Largest distance between the particles of two frames (same set-up).
double max_distance(const Frame& a, const Frame& b) {
  double worst = 0;
  for (long i = 0; i < a.n; ++i) {
    double d2 = 0;
    for (int d = 0; d < a.dim; ++d) d2 += std::pow(a.x[d * a.n + i] - b.x[d * b.n + i], 2);
    worst = std::max(worst, std::sqrt(d2));
  }
  return worst;
}

}  // namespace

// A block on a Coulomb floor slides at a = g (sin theta - mu cos theta): the friction impulse
// of every sliding node is mu times its normal impulse, so the momentum balance of the block
// holds whatever its ends do. Measured: the slope of the mean velocity over 0.1-0.3 s (the
// elastic settling of the stress-free block is over).
TEST(MpmBoundary, BlockOnFrictionalInclineSlidesAtTheCoulombRate) {
  const std::vector<double> x{1.0, 0.0};
  struct Case {
    double theta, mu;
  };
  for (const Case c : {Case{30 * kDeg, 0.2}, Case{30 * kDeg, 0.4}, Case{20 * kDeg, 0.0}}) {
    const SceneSetup su = make_setup(incline_scene(2, c.theta, c.mu));
    const Motion mo = mean_motion(su, x, 0.01);
    const double a = slope(mo, 0.1);
    const double exact = kG * (std::sin(c.theta) - c.mu * std::cos(c.theta));
    std::printf("incline %.0f deg, mu %.2f: a = %.4f m/s^2, g (sin - mu cos) = %.4f (%.2f %%)\n", c.theta / kDeg,
                c.mu, a, exact, 100 * (a / exact - 1));
    EXPECT_NEAR(a, exact, 0.02 * exact);
  }
}

// Below the friction angle (tan 10 deg = 0.18 < mu = 0.3) the block stays where it is. It is
// first settled for 0.1 s with local damping (the stress-free block falls onto the floor);
// over the next 0.2 s the base of its middle half (the bottom row of points, 0.2 < x < 0.4)
// moves by a small fraction of what it slides with mu = 0.1 (tan 10 deg - mu = 0.076). The
// downhill end slumps at the material's angle of repose and drags the block's top a little.
TEST(MpmBoundary, BlockOnFrictionalInclineStaysPutBelowTheFrictionAngle) {
  const double theta = 10 * kDeg;
  auto base_displacement = [&](double mu) {
    Scene sc = incline_scene(2, theta, mu);
    Stage settle;
    settle.name = "settle";
    settle.duration = 0.1;
    settle.damping = 0.5;
    sc.stages[0].duration = 0.2;
    sc.stages.insert(sc.stages.begin(), settle);
    const Motion mo = mean_motion(make_setup(sc), {1.0, 0.0}, 0.02);
    const Frame &a = mo.stage_end.at(0), &b = mo.stage_end.at(1);
    double most = 0;
    for (long i = 0; i < a.n; ++i)
      if (a.x[i] > 0.2 && a.x[i] < 0.4 && a.x[a.n + i] < 0.01) most = std::max(most, std::fabs(b.x[i] - a.x[i]));
    return most;
  };
  const double stuck = base_displacement(0.3), sliding = base_displacement(0.1);
  std::printf("incline 10 deg: the base of the block moves %.2e m in 0.2 s with mu 0.3, %.2e m with mu 0.1\n", stuck,
              sliding);
  EXPECT_LT(stuck, 0.01 * sliding);
  EXPECT_GT(sliding, 0.01);
}

// A free-slip floor is a frictional floor with mu = 0, a no-slip floor one with a large mu:
// the block on the 20 deg incline after 0.1 s, in 2D and in 3D (a slab between free-slip
// walls in z). The two limits differ only where a floor node separates (the contact leaves it
// free, the mask holds it). The comparisons tell free slip from no slip: the block slides
// ~17 mm on the one and stays on the other.
TEST(MpmBoundary, FreeSlipAndNoSlipAreTheLimitsOfFriction) {
  for (int dim : {2, 3}) {
    auto final_frame = [&](std::optional<double> mu, bool no_slip) {
      Scene sc = incline_scene(dim, 20 * kDeg, mu, no_slip);
      sc.stages[0].duration = 0.1;
      return mean_motion(make_setup(sc), std::vector<double>(dim, 0.0), 0.05).last;
    };
    const Frame free_slip = final_frame(std::nullopt, false), no_slip = final_frame(std::nullopt, true);
    const Frame mu0 = final_frame(0.0, false), mu_large = final_frame(1e3, false);
    const double apart = max_distance(free_slip, no_slip);
    const double d0 = max_distance(mu0, free_slip), dl = max_distance(mu_large, no_slip);
    std::printf("%dD, 0.1 s on 20 deg: |mu 0 - free slip| %.2e m, |mu 1e3 - no slip| %.2e m, "
                "|free slip - no slip| %.2e m\n", dim, d0, dl, apart);
    EXPECT_GT(apart, 0.01);
    EXPECT_LT(d0, 1e-4 * apart);
    EXPECT_LT(dl, 1e-4 * apart);
  }
}

// The flume's base polyline with friction: a 30 deg slope levelling out at y = 0, gravity
// vertical, a block 60 mm thick on the slope. The contact takes the normal of the segment
// above each node, so the block slides down the staircase of grid nodes under the slope at
// g (sin - mu cos) along it (over 0.05-0.25 s, before it reaches the level part). With
// mu = 1.0 it stays: after 0.1 s of damped settling the base of its middle third moves as
// little as on the no-slip base (the material above creeps; its downhill end slumps).
// Friction acts node by node, and on the staircase the ratio of tangential to normal force
// scatters about tan 30 deg = 0.58 from node to node: at mu = 0.7 the base still creeps
// (6 mm in 0.15 s, against 2 mm no-slip and 50 mm sliding at mu = 0.2; on a 20 deg slope mu 0.5
// gives 0.6 mm against 26 mm), so stick needs mu well above tan theta there.
TEST(MpmBoundary, FrictionalBasePolylineSlidesAtTheCoulombRate) {
  const double theta = 30 * kDeg, top = 0.4, run = top / std::tan(theta);
  const std::vector<double> along{std::cos(theta), -std::sin(theta)};
  auto at = [&](double s, double up, int d) {  // s along the slope from its top, up normal to it
    return d == 0 ? s * std::cos(theta) + up * std::sin(theta) : top - s * std::sin(theta) + up * std::cos(theta);
  };
  auto slide = [&](std::optional<double> mu, double settle) {
    Scene sc = block_base_scene(2);
    sc.origin = {0.0, 0.0};
    sc.size = {1.2, 0.5};
    sc.base = BaseLine{{0.0, run, 1.2}, {top, 0.0, 0.0}};
    sc.base->mu = mu;
    sc.walls = {Wall{0, false, 0.0, false, "wall[0].side"}};
    Body b;
    b.poly_x = {at(0.1, 0, 0), at(0.4, 0, 0), at(0.4, 0.06, 0), at(0.1, 0.06, 0)};
    b.poly_y = {at(0.1, 0, 1), at(0.4, 0, 1), at(0.4, 0.06, 1), at(0.1, 0.06, 1)};
    sc.bodies = {b};
    sc.stages[0].duration = 0.25 - settle;
    if (settle > 0) {
      Stage st;
      st.duration = settle;
      st.damping = 0.5;
      sc.stages.insert(sc.stages.begin(), st);
    }
    return mean_motion(make_setup(sc), along, 0.01);
  };
  for (double mu : {0.0, 0.2}) {
    const double a = slope(slide(mu, 0), 0.05), exact = kG * (std::sin(theta) - mu * std::cos(theta));
    std::printf("base polyline, 30 deg, mu %.2f: a = %.4f m/s^2 along the slope, g (sin - mu cos) = %.4f (%.2f %%)\n",
                mu, a, exact, 100 * (a / exact - 1));
    EXPECT_NEAR(a, exact, 0.02 * exact);
  }
  auto base_displacement = [&](std::optional<double> mu) {
    const Motion mo = slide(mu, 0.1);
    const Frame &f0 = mo.stage_end.at(0), &f1 = mo.stage_end.at(1);
    double most = 0;
    for (long i = 0; i < f0.n; ++i) {
      const double s = f0.x[i] * along[0] + (f0.x[f0.n + i] - top) * along[1];
      const double up = f0.x[i] * std::sin(theta) + (f0.x[f0.n + i] - top) * std::cos(theta);
      if (s > 0.2 && s < 0.3 && up < 0.01)
        most = std::max(most, std::fabs((f1.x[i] - f0.x[i]) * along[0] + (f1.x[f0.n + i] - f0.x[f0.n + i]) * along[1]));
    }
    return most;
  };
  const double held = base_displacement(1.0), no_slip = base_displacement(std::nullopt);
  const double sliding = base_displacement(0.2);
  std::printf("base polyline, 30 deg: the base of the block moves %.2e m in 0.15 s with mu 1.0, %.2e m no-slip, "
              "%.2e m with mu 0.2\n", held, no_slip, sliding);
  EXPECT_GT(sliding, 0.03);
  EXPECT_LT(held, 0.1 * sliding);
  EXPECT_LT(held, 2 * no_slip);
}

// The base's contact normal points into the base, below the segment, for either slope: a node
// under the polyline moving into it loses its normal velocity (free slip: all of it, as the
// motion is normal), one moving away or along the segment keeps its velocity.
TEST(MpmBoundary, BaseSegmentNormalPointsIntoTheBase) {
  using G = GridLayout<2>;
  GridDesc<2, double> grid{{0.0, 0.0}, 0.1, 10.0, {3, 3}, 9};
  grid.nx = 3;
  const long n = 9;
  const long off = contact_table_offset(n);
  std::vector<std::uint64_t> buf((off + sizeof(ContactTable) + sizeof(BaseSegment)) / 8 + 1);  // 8-byte aligned
  auto* mask = reinterpret_cast<std::uint8_t*>(buf.data());
  auto& c = *new (mask + off) ContactTable();
  c.h = 0.1;
  c.tol = 1e-10;
  c.n_segments = 1;
  c.base_mu = 0;
  auto* seg = reinterpret_cast<BaseSegment*>(&c + 1);
  std::vector<double> a(G::N * n, 0.0);
  GridView<double> gv{a.data(), n, mask, 0};
  const long I = 4;  // the node at (0.1, 0.1), below either segment (0.2 high at x = 0.1)
  auto after = [&](double vx, double vy) {
    gv.f(G::VNEW, I) = vx;
    gv.f(G::VNEW + 1, I) = vy;
    contact_node<2, double>(gv, I, grid, 0.0);
    return std::pair<double, double>{gv.f(G::VNEW, I), gv.f(G::VNEW + 1, I)};
  };
  // falling to the right: into the base is down and to the left
  *seg = BaseSegment{0.0, 0.3, 0.2, 0.1};
  auto v = after(-1.0, -1.0);
  EXPECT_NEAR(v.first, 0.0, 1e-15);
  EXPECT_NEAR(v.second, 0.0, 1e-15);
  EXPECT_EQ(after(1.0, 1.0), std::make_pair(1.0, 1.0));    // separating
  v = after(1.0, -1.0);                                     // along the segment
  EXPECT_NEAR(v.first, 1.0, 1e-15);
  EXPECT_NEAR(v.second, -1.0, 1e-15);
  // rising to the right: into the base is down and to the right
  *seg = BaseSegment{0.0, 0.1, 0.2, 0.3};
  v = after(1.0, -1.0);
  EXPECT_NEAR(v.first, 0.0, 1e-15);
  EXPECT_NEAR(v.second, 0.0, 1e-15);
  EXPECT_EQ(after(-1.0, 1.0), std::make_pair(-1.0, 1.0));  // separating
  // half of a velocity straight down is normal to a 45-degree segment: the tangential half stays
  v = after(0.0, -2.0);
  EXPECT_NEAR(v.first, -1.0, 1e-15);
  EXPECT_NEAR(v.second, -1.0, 1e-15);
}

namespace {

// The tiny column (20 mm, frictional) consolidated behind its gate for 0.06 s; in the second
// stage, 0.2 s long, the gate is lifted at lift_speed (0: removed at once).
Scene gate_column(double lift_speed) {
  Scene sc = test::tiny_column(ModelKind::Frictional);
  sc.stages[1].duration = 0.2;
  sc.tracks.clear();
  sc.output.times.clear();
  if (lift_speed > 0) {
    sc.stages[1].gate = sc.stages[0].gate;
    sc.stages[1].gate->lift_speed = lift_speed;
  }
  return sc;
}

}  // namespace

// The lifting gate in the grid update: a node of the gate's half-space (x >= 0.2) is held
// (normal component) at and above the lower edge, at y = lift_speed (t - t_stage) with t_stage
// the start of the gate's stage, and free below it; the floor holds its own nodes throughout.
TEST(MpmBoundary, LiftingGateHoldsTheNodesAboveItsLowerEdge) {
  const double speed = 0.5;
  const SceneSetup su = make_setup(gate_column(speed));
  const double t_stage = su.scene.stages[0].duration;
  using FR = FrictionalModel<double>;
  StepParams<2, double, FR> sp{};
  sp.grid = test::grid_of(su);
  sp.dt = 1e-4;
  using G = GridLayout<2>;
  const long nn = su.n_nodes;
  std::vector<double> grid(static_cast<size_t>(G::N) * nn, 0.0);
  const GridView<double> gv{grid.data(), nn, su.stage_masks[1].data()};
  const double h = su.scene.h;
  for (double tau : {0.0, 0.01, 0.05, 0.1, 0.15}) {
    const double edge = speed * tau;
    sp.t = t_stage + tau;
    for (const double x : {0.2, 0.3}) {  // on the gate's plane and beyond it
      for (int j = 0; j < su.nodes[1]; ++j) {
        const int I[2] = {static_cast<int>(std::lround((x - su.origin[0]) / h)), j};
        const long k = sp.grid.linear(I);
        const double y = su.origin[1] + j * h;
        gv.f(G::M, k) = 1.0;
        gv.f(G::P, k) = 1.0;       // moving at 1 m/s in x (through the gate)
        gv.f(G::P + 1, k) = 0.5;   // and 0.5 m/s up (away from the floor)
        grid_update_node<2, double, FR, true, true>(gv, k, sp);
        const bool floor = y <= 1e-12;
        const bool held = y >= edge - 1e-12;
        EXPECT_EQ(gv.f(G::VNEW, k), floor || held ? 0.0 : 1.0) << "tau " << tau << " x " << x << " y " << y;
        EXPECT_EQ(gv.f(G::VNEW + 1, k), floor ? 0.0 : 0.5) << "tau " << tau << " x " << x << " y " << y;
      }
    }
  }
  // In front of the gate (x < 0.2) nothing is held but the floor.
  const int I[2] = {static_cast<int>(std::lround((0.1 - su.origin[0]) / h)), su.nodes[1] / 2};
  const long k = sp.grid.linear(I);
  gv.f(G::M, k) = 1.0;
  gv.f(G::P, k) = 1.0;
  sp.t = t_stage;
  grid_update_node<2, double, FR, true, true>(gv, k, sp);
  EXPECT_EQ(gv.f(G::VNEW, k), 1.0);
}

// The column behind a gate lifted at 0.5 m/s flows out under it: the mass in front of the gate
// lags the mass released by removing the gate at once, and every point that has passed the
// gate's plane lies below the lower edge (within one cell: the lowest held node row is at or
// above the edge). With linear hats on the 20 mm grid a point moves freely once both node rows
// of its cell are below the edge (the floor is no-slip): the first points pass 0.16 s after the
// release, at most 40 mm high, against 0.06 s when the gate is removed at once.
TEST(MpmBoundary, LiftingGateReleasesTheColumnProgressively) {
  const double speed = 0.5, x_gate = 0.2, h = 0.02;
  struct Outflow {
    std::vector<double> t, share, top;  // share of the points in front of the gate, highest of them
  };
  auto outflow = [&](double lift_speed) {
    const SceneSetup su = make_setup(gate_column(lift_speed));
    const double t0 = su.scene.stages[0].duration;
    Outflow o;
    run_sampled(su, 0.02, [&](const Frame& f, double t, int stage) {
      if (stage != 1) return;
      double out = 0, top = 0;
      for (long i = 0; i < f.n; ++i)
        if (f.x[i] > x_gate) {
          out += 1.0;
          top = std::max(top, f.x[f.n + i]);
        }
      o.t.push_back(t - t0);
      o.share.push_back(out / f.n);
      o.top.push_back(top);
    });
    return o;
  };
  const Outflow lifted = outflow(speed), instant = outflow(0);
  ASSERT_EQ(lifted.t.size(), instant.t.size());
  for (size_t k = 0; k < lifted.t.size(); ++k) {
    const double edge = speed * lifted.t[k];
    std::printf("%.2f s after the release: %.3f of the points in front of the gate (lifted at 0.5 m/s; removed: "
                "%.3f), the highest at %.3f m, the edge at %.3f m\n", lifted.t[k], lifted.share[k], instant.share[k],
                lifted.top[k], edge);
    EXPECT_LE(lifted.share[k], instant.share[k]) << "t " << lifted.t[k];
    if (instant.share[k] > 0) EXPECT_LT(lifted.share[k], 0.5 * instant.share[k]) << "t " << lifted.t[k];
    EXPECT_LE(lifted.top[k], edge + h) << "t " << lifted.t[k];
    if (k > 0) EXPECT_GE(lifted.share[k], lifted.share[k - 1]);
  }
  EXPECT_GT(lifted.share.back(), 0.02);  // it does release
}
