// Terrain contact that holds (issue 51; docs/mpm_terrain.md, "Held nodes and contact"): a
// 10 x 10 x 4 cm release volume on a plane dipping 30 deg, settled and then free, measured for
// sinking, creep (mu 0.7 holds it) and the Coulomb acceleration (mu 0.3). CPU twin.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <unistd.h>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <memory>
#include <string>
#include <vector>

#include <granflow/io/raster.hpp>
#include <granflow/mpm/kernels.hpp>
#include <granflow/mpm/driver.hpp>
#include <granflow/mpm/maps.hpp>
#include <granflow/mpm/scene_file.hpp>
#include <granflow/mpm/runner.hpp>
#include <granflow/mpm/scene.hpp>

#include "sampled_run.hpp"
#include "terrain_scene.hpp"
#include "test_constants.hpp"
#include "tiny_column.hpp"

using namespace granflow;
using namespace granflow::mpm;
using namespace granflow::mpm::test;

namespace {

struct Slide {
  double h = 0.02;
  ShapeKind shape = ShapeKind::Linear;
  double plan_deg = 0;  // dip direction in plan, from x towards z
  double mu = 0.3;
  Terrain::Contact contact = Terrain::Contact::Support;
  bool level = false;   // a level raster with gravity tilted by the dip instead of a tilted raster
  double settle = 0.1, free = 0.4;
  double theta_deg = 30, phi_c_deg = 50;
  double block = 0.10, thick = 0.04;
};

struct SlideResult {
  bool ok = true;
  long points = 0;
  double deepest = 0;  // largest depth below the ground over the samples [point spacings]
  double creep = 0;    // mean down-dip displacement of the base's middle third after the settle [m]
  double creep_rate = 0;  // their mean down-dip velocity at the end [m/s]
  double creep_half = 0;  // their displacement over the first half of the free stage [m]
  double accel = 0;    // fitted down-dip acceleration of the centre of mass over 0.1-0.4 s after it [m/s^2]
  double coulomb = 0;  // g (sin theta - mu cos theta), at least 0
  double seconds = 0;  // CPU time of the run
  long steps = 0;
};

// A square raster of n x n cells of the plane z = -(sx e + sz n) + above.
std::shared_ptr<const io::Raster> plane(double west, double south, double cell, long n, double sx, double sz,
                                        double above = 0) {
  return raster(west, south, cell, n, n, [&](double e, double nn) { return above - (sx * e + sz * nn); });
}

SlideResult run_slide(const Slide& c) {
  const double th = c.theta_deg * kDeg, ph = c.plan_deg * kDeg;
  const double dx = std::cos(ph), dz = std::sin(ph);
  const double tn = c.level ? 0.0 : std::tan(th);
  const double travel = 0.5 * kG * std::max(0.0, std::sin(th) - c.mu * std::cos(th)) * c.free * c.free + 0.02;
  const double margin = 2 * c.h + 0.01;
  // footprint: the block and its travel along the dip's plan direction
  const double Lx = std::ceil((margin * 2 + c.block + travel * std::fabs(dx)) / c.h) * c.h;
  const double Lz = std::ceil((margin * 2 + c.block + travel * std::fabs(dz)) / c.h) * c.h;
  const double drop = tn * (Lx * std::fabs(dx) + Lz * std::fabs(dz));
  const double H = drop + 2 * c.h + 0.013;  // ground at y = H - tn (x dx + z dz), off the node rows
  const double Ly = std::ceil((H + c.thick / std::max(0.5, std::cos(th)) + 0.04) / c.h) * c.h;
  auto ground = plane(-0.1, -0.1, 0.05, static_cast<long>((std::max(Lx, Lz) + 0.3) / 0.05), tn * dx, tn * dz);

  Scene sc = terrain_scene({Lx, Ly, Lz}, c.h, ground, {0.0, 0.0, -H}, c.mu);
  sc.material.params.f.phi_c = c.phi_c_deg * kDeg;
  sc.dt = 1e-4 * std::min(1.0, c.h / 0.01);
  sc.shape = c.shape;
  sc.ppc_axis = 2;
  sc.initial.geostatic = true;
  const std::vector<double> dip = c.level ? std::vector<double>{dx, 0.0, dz}
                                          : std::vector<double>{std::cos(th) * dx, -std::sin(th), std::cos(th) * dz};
  if (c.level) sc.gravity = {kG * std::sin(th) * dx, -kG * std::cos(th), kG * std::sin(th) * dz};
  Stage settle = sc.stages[0];
  settle.name = "settle";
  settle.duration = c.settle;
  settle.damping = 0.5;
  sc.stages[0].duration = c.free;
  sc.stages.insert(sc.stages.begin(), settle);
  sc.terrain->contact = c.contact;
  const double a0 = margin + (dx < 0 ? travel * std::fabs(dx) : 0.0), b0 = margin + (dz < 0 ? travel * std::fabs(dz) : 0.0);
  Body body;
  body.top = plane(-0.1, -0.1, 0.05, ground->ncols, tn * dx, tn * dz, c.thick);
  body.plan_x = {a0, a0 + c.block, a0 + c.block, a0};
  body.plan_z = {b0, b0, b0 + c.block, b0 + c.block};
  sc.bodies = {body};
  const SceneSetup su = make_setup(sc);

  auto ground_y = [&](double x, double z) { return H - tn * (x * dx + z * dz); };
  const double cs = c.level ? 1.0 : std::cos(th);  // normal distance = vertical height x cos
  const long n = su.particles.n;
  std::vector<double> m = su.particles.m;
  double M = 0;
  for (double v : m) M += v;
  SlideResult out;
  out.points = n;
  out.coulomb = kG * std::max(0.0, std::sin(th) - c.mu * std::cos(th));
  Motion mo;  // the centre of mass's down-dip velocity over the free stage, from its start
  Frame settled, last, half;
  bool have_settled = false;
  const auto t0 = std::chrono::steady_clock::now();
  run_sampled(su, 0.01, [&](const Frame& f, double t, int si) {
    double deepest = 0, p = 0;
    for (long i = 0; i < f.n; ++i) {
      const double d = (f.x[n + i] - ground_y(f.x[i], f.x[2 * n + i])) * cs;
      deepest = std::max(deepest, -d);
      for (int k = 0; k < 3; ++k) p += m[i] * f.v[k * f.n + i] * dip[k];
    }
    out.deepest = std::max(out.deepest, deepest / su.spacing);
    if (si == 0 && t >= c.settle - 1e-9 && !have_settled) {
      settled = f;
      have_settled = true;
    }
    if (si == 1) {
      mo.t.push_back(t - c.settle);
      mo.v.push_back(p / M);
    }
    last = f;
    if (si == 1 && std::fabs(t - c.settle - c.free / 2) < 1e-6) half = f;
    out.steps += 1;
  });
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!have_settled || last.n == 0 || mo.t.empty() || mo.t.back() < c.free - 1e-6) {
    out.ok = false;
    return out;
  }
  // creep: points within one spacing of the ground at the settle's end, in the middle third
  double s = 0, cnt = 0;
  for (long i = 0; i < n; ++i) {
    const double x0 = su.particles.x[i], z0 = su.particles.x[2 * n + i];
    if (x0 < a0 + c.block / 3 || x0 > a0 + 2 * c.block / 3 || z0 < b0 + c.block / 3 || z0 > b0 + 2 * c.block / 3)
      continue;
    const double d = (settled.x[n + i] - ground_y(settled.x[i], settled.x[2 * n + i])) * cs;
    if (d > su.spacing) continue;
    double u = 0, w = 0, uh = 0;
    for (int k = 0; k < 3; ++k) {
      u += (last.x[k * n + i] - settled.x[k * n + i]) * dip[k];
      w += last.v[k * n + i] * dip[k];
      uh += (half.x[k * n + i] - settled.x[k * n + i]) * dip[k];
    }
    s += u;
    out.creep_rate += w;
    out.creep_half += uh;
    cnt += 1;
  }
  out.creep = cnt > 0 ? s / cnt : 0;
  out.creep_rate /= std::max(1.0, cnt);
  out.creep_half /= std::max(1.0, cnt);
  out.accel = fitted_rate(mo, 0.1, 0.4);
  return out;
}

const char* name_of(Terrain::Contact k) {
  return k == Terrain::Contact::Nodes ? "nodes" : "support";
}

void print(const Slide& c, const SlideResult& r) {
  std::printf("%-7s %-9s h %2.0f mm dip %2.0f%s mu %.1f: %s %6ld points, deepest %5.2f spacings, creep %6.2f mm, "
              "(half %5.2f, %5.1f mm/s at the end), accel %7.4f (Coulomb %.4f, %+6.2f %%), %.1f s\n",
              name_of(c.contact), c.shape == ShapeKind::Linear ? "linear" : "quadratic", c.h * 1e3, c.plan_deg,
              c.level ? " level" : "", c.mu, r.ok ? "ran" : "STOPPED", r.points, r.deepest, r.creep * 1e3, r.creep_half * 1e3, r.creep_rate * 1e3, r.accel,
              r.coulomb, r.coulomb > 0 ? 100 * (r.accel / r.coulomb - 1) : 0.0, r.seconds);
  std::fflush(stdout);
}

}  // namespace

// The goals of issue 51 on the 20 mm grid, linear and quadratic, dipping along x and 45 deg in plan
// (along z, linear: the mirror image of x, the same numbers within 1e-9; the 10 mm rows of
// docs/mpm_terrain.md come from TerrainContact.OneCase, minutes of CPU beyond CI's budget): no point deeper than 0.1 spacings below
// the raster at any sample, a base that moves at most 1 mm in 0.4 s with mu 0.7 (tan 30 deg =
// 0.577), and with mu 0.3 the Coulomb acceleration g (sin 30 - 0.3 cos 30) within 1 %. The
// nodes-only contact (terrain.contact = "nodes") fails the first two on the same block: the
// measures tell the two apart.
TEST(TerrainContact, SlideHoldsSticksAndSlipsAt20mm) {
  for (auto sh : {ShapeKind::Linear, ShapeKind::QuadraticBSpline})
    for (double plan : {0.0, 45.0})
      for (double mu : {0.7, 0.3}) {
        Slide c;
        c.shape = sh;
        c.plan_deg = plan;
        c.mu = mu;
        const SlideResult r = run_slide(c);
        print(c, r);
        ASSERT_TRUE(r.ok);
        EXPECT_LE(r.deepest, 0.1);
        if (mu > 0.6)
          EXPECT_LE(std::fabs(r.creep), 1e-3);
        else
          EXPECT_NEAR(r.accel, r.coulomb, 0.01 * r.coulomb);
      }
  for (double mu : {0.7, 0.3}) {  // dipping along z: the mirror image of x, the same numbers
    Slide x, z;
    x.mu = z.mu = mu;
    z.plan_deg = 90;
    const SlideResult rx = run_slide(x), rz = run_slide(z);
    print(z, rz);
    EXPECT_NEAR(rz.creep, rx.creep, 1e-9);
    EXPECT_NEAR(rz.accel, rx.accel, 1e-9);
    EXPECT_NEAR(rz.deepest, rx.deepest, 1e-9);
  }
  Slide old;
  old.contact = Terrain::Contact::Nodes;
  old.mu = 0.7;
  const SlideResult r = run_slide(old);
  print(old, r);
  EXPECT_GT(r.deepest, 0.3);
  EXPECT_GT(r.creep, 5e-3);
}

// The same block, CI-sized for the sanitizer stage (tests/plain_only.txt): settled 0.05 s, free
// 0.1 s, dipping 45 deg in plan, linear hats: nothing sinks below 0.1 spacings, and the base
// holds with mu 0.7 (at most 0.25 mm; measured 0.19 mm).
TEST(TerrainContact, SlideHoldsCiSized) {
  Slide c;
  c.plan_deg = 45;
  c.mu = 0.7;
  c.settle = 0.05;
  c.free = 0.1;
  const SlideResult r = run_slide(c);
  print(c, r);
  ASSERT_TRUE(r.ok);
  EXPECT_LE(r.deepest, 0.1);
  EXPECT_LE(std::fabs(r.creep), 2.5e-4);
}

// deposit.csv's points_below_ground and max_depth_below_ground: three points placed 1, 2 and 3
// mm below a plane dipping 30 deg, and one above it: 3 points, the deepest 3 mm x cos 30 deg
// along the normal.
TEST(TerrainContact, DepositRowsCountThePointsBelowTheGround) {
  const double th = 30 * kDeg, tn = std::tan(th);
  auto ground = plane(-0.1, -0.1, 0.05, 12, tn, 0.0);
  Scene sc = terrain_scene({0.2, 0.2, 0.1}, 0.02, ground, {0.0, 0.0, -0.15}, 0.3);
  sc.stages[0].duration = 0.01;
  Body b;
  b.box_min = {0.08, 0.14, 0.04};
  b.box_max = {0.12, 0.18, 0.06};
  sc.bodies = {b};
  const SceneSetup su = make_setup(sc);
  TerrainMaps maps(su);
  Frame f;
  f.dim = 3;
  f.n = 4;
  const double xs[4] = {0.05, 0.1, 0.15, 0.1}, dy[4] = {-1e-3, -2e-3, -3e-3, 1e-3};
  f.x.assign(12, 0.05);
  f.v.assign(12, 0.0);
  for (int i = 0; i < 4; ++i) {
    f.x[i] = xs[i];
    f.x[4 + i] = 0.15 - tn * xs[i] + dy[i];
  }
  maps.sample(0.0, 0.0, f);
  const DepositRow& r = maps.state().deposit.back();
  EXPECT_EQ(r.ground_points, 3.0);
  EXPECT_NEAR(r.ground_depth, 3e-3 * std::cos(th), 1e-12);
}

// The example to copy, mpm/scenes/layered_slope_ci.toml: a strong block (flume set, phi_c 38 deg)
// on a weak layer three cells thick (column-collapse set, 19.8 deg) on a 30 deg raster with mu 0.6.
// It runs to its end and writes the maps, deposit.csv (no point below the raster at any sample)
// and the terrain's force in obstacle_forces.csv; the block's front goes further on the weak
// layer than on a layer of its own set (--params weak=flume: the slope then holds the layer, and
// the block only slumps): measured 10.4 cm against 8.1 cm in 0.2 s.
TEST(TerrainContact, LayeredSlopeExampleSlidesOnItsWeakLayer) {
  const std::string scene = GRANFLOW_SOURCE_DIR "/mpm/scenes/layered_slope_ci.toml";
  auto front_advance = [&](const std::string& weak_set, const std::filesystem::path& out) {
    SceneOverrides o;
    if (!weak_set.empty()) add_params(o, "weak=" + weak_set);
    const SceneSetup su = make_setup_for_file(load_scene(scene, o));
    EXPECT_EQ(su.scene.material_count(), 2);
    auto r = make_cpu_runner(su);
    RunOptions opt;
    opt.progress = false;
    opt.out_dir = out.string();
    const RunSummary s = run(su, *r, opt);
    EXPECT_TRUE(s.ok) << s.message;
    const size_t nm = 2, rows = s.series.size();
    if (!s.ok || rows < 2 || s.material_series.size() != nm * rows) return 0.0;
    return s.material_series[(rows - 1) * nm].runout - s.material_series[0].runout;  // material 0: strong
  };
  const auto dir = std::filesystem::temp_directory_path() / ("granflow_layered_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  const double layered = front_advance("", dir / "layered"), strong = front_advance("flume", dir / "strong");
  std::printf("layered slope: the strong block's front advances %.4f m on the weak layer, %.4f m on a strong one\n",
              layered, strong);
  EXPECT_GT(layered, strong + 0.01);
  for (const char* f : {"maps/deposit_thickness.asc", "maps/max_speed.asc", "maps/max_depth.asc", "deposit.csv",
                        "obstacle_forces.csv", "materials.csv"})
    EXPECT_TRUE(std::filesystem::exists(dir / "layered" / f)) << f;
  std::ifstream dep(dir / "layered" / "deposit.csv");
  std::string line;
  std::getline(dep, line);
  long rows = 0;
  while (std::getline(dep, line)) {
    ++rows;
    EXPECT_EQ(line.substr(line.rfind(',', line.rfind(',') - 1) + 1), "0,0") << line;  // no point below the raster
  }
  EXPECT_GE(rows, 20);
  std::ifstream forces(dir / "layered" / "obstacle_forces.csv");
  std::ostringstream all;
  all << forces.rdbuf();
  EXPECT_NE(all.str().find(",terrain,total,"), std::string::npos);
  std::filesystem::remove_all(dir);
}

// MPM-Geomechanics' terrain-contact verification (data/terrain_contact/SOURCES.md): a cube of 10
// m, |g| = 10 m/s^2 at 45 deg to the ground, mu 0 and 0.3, one point near the leading bottom
// corner (their (11.75, 6.75, 2.25), z up; ours (11.75, 2.25, 6.75), y up) followed for 2 s. Two
// grounds: a level raster at y = 2 with gravity tilted 45 deg along x (their set-up), and a raster
// dipping 45 deg along x with vertical gravity. Our law is granular: the flume set made strong
// (phi_c 60 deg) and stiff (K0 x 10), a geostatic start and no settle (with mu 0 nothing holds a
// block during a damped settle). Writes the point's and the centre of mass's displacement along
// the ground, and the centre's rise off it (w_centre: its slump), every 0.05 s to GRANFLOW_EXTERNAL_OUT (scripts/plot_terrain_external.py draws it
// with their CSVs and the closed form u = 1/2 g (sin 45 - mu cos 45) t^2).
TEST(TerrainContact, ExternalSlidingBlock) {
  const char* out = std::getenv("GRANFLOW_EXTERNAL_OUT");
  if (!out) GTEST_SKIP() << "set GRANFLOW_EXTERNAL_OUT=file.csv";
  std::ofstream csv(out);
  csv << "ground,mu,t,u_point,u_centre,u_exact,w_centre\n";
  const double g = 10.0, th = 45 * kDeg, c = std::cos(th);
  for (const bool level : {true, false})
    for (const double mu : {0.0, 0.3}) {
      const double H = level ? 2.0 : 2.0 + 32.0;  // the ground at x = 0
      auto elevation = [&](double e, double) { return level ? 0.0 : -e; };
      auto ground = raster(-2.0, -2.0, 1.0, 40, 20, elevation);
      Scene sc = terrain_scene(level ? std::vector<double>{32.0, 16.0, 14.0} : std::vector<double>{32.0, 48.0, 14.0}, 1.0,
                               ground, {0.0, 0.0, -H}, mu);
      sc.material.params.f.phi_c = 60 * kDeg;
      sc.material.params.f.K0 *= 10;
      sc.dt = 1e-3;
      sc.ppc_axis = 2;
      sc.initial.geostatic = true;
      sc.gravity = level ? std::vector<double>{g * std::sin(th), -g * c, 0.0} : std::vector<double>{0.0, -g, 0.0};
      sc.stages[0].duration = 2.0;
      Body body;
      if (level) {
        body.box_min = {2.0, 2.0, 2.0};
        body.box_max = {12.0, 12.0, 12.0};
      } else {  // 10 m thick along the normal: 10 / cos 45 vertically
        body.top = raster(-2.0, -2.0, 1.0, 40, 20, [&](double e, double nn) { return elevation(e, nn) + 10.0 / c; });
        body.plan_x = {2.0 * c, 12.0 * c, 12.0 * c, 2.0 * c};
        body.plan_z = {2.0, 2.0, 12.0, 12.0};
      }
      sc.bodies = {body};
      const SceneSetup su = make_setup(sc);
      const long n = su.particles.n;
      const std::vector<double> dir = level ? std::vector<double>{1.0, 0.0, 0.0} : std::vector<double>{c, -c, 0.0};
      const std::vector<double> up = level ? std::vector<double>{0.0, 1.0, 0.0} : std::vector<double>{c, c, 0.0};
      // the point: their leading bottom corner point; on the slope the lowest point of the
      // leading column nearest z = 6.75
      long pick = 0;
      double best = 1e300;
      for (long i = 0; i < n; ++i) {
        const double x = su.particles.x[i], y = su.particles.x[n + i], z = su.particles.x[2 * n + i];
        const double d = level ? std::hypot(x - 11.75, y - 2.25, z - 6.75)
                               : std::hypot(x - (12.0 * c - 0.25), z - 6.75) + 1e-3 * (y - (H - x));
        if (d < best) {
          best = d;
          pick = i;
        }
      }
      std::vector<double> m = su.particles.m;
      double M = 0, c0[3] = {0, 0, 0};
      for (long i = 0; i < n; ++i) {
        M += m[i];
        for (int k = 0; k < 3; ++k) c0[k] += m[i] * su.particles.x[k * n + i];
      }
      run_sampled(su, 0.05, [&](const Frame& f, double tt, int) {
        double u_point = 0, uc = 0, wc = 0;
        for (int k = 0; k < 3; ++k) {
          u_point += (f.x[k * n + pick] - su.particles.x[k * n + pick]) * dir[k];
          double ck = 0;
          for (long i = 0; i < n; ++i) ck += m[i] * f.x[k * n + i];
          uc += (ck - c0[k]) / M * dir[k];
          wc += (ck - c0[k]) / M * up[k];
        }
        csv << (level ? "level" : "slope") << ',' << mu << ',' << tt << ',' << u_point << ',' << uc << ','
            << 0.5 * g * (std::sin(th) - mu * c) * tt * tt << ',' << wc << '\n';
      });
      std::printf("%s ground, mu %.1f: %ld points, the point at (%.2f, %.2f, %.2f)\n", level ? "level" : "45 deg", mu, n,
                  su.particles.x[pick], su.particles.x[n + pick], su.particles.x[2 * n + pick]);
    }
}

// The comparison of docs/mpm_terrain.md: GRANFLOW_CONTACT_MATRIX=1 runs it (minutes).
TEST(TerrainContact, ComparisonMatrix) {
  if (!std::getenv("GRANFLOW_CONTACT_MATRIX")) GTEST_SKIP() << "set GRANFLOW_CONTACT_MATRIX=1";
  const std::string only = std::getenv("GRANFLOW_CONTACT_MATRIX");
  for (auto k : {Terrain::Contact::Nodes, Terrain::Contact::Support})
    for (double h : {0.02, 0.01})
      for (auto sh : {ShapeKind::Linear, ShapeKind::QuadraticBSpline})
        for (double mu : {0.3, 0.7}) {
          Slide c;
          c.contact = k;
          c.h = h;
          c.shape = sh;
          c.mu = mu;
          if (only != "1" && only.find(name_of(k)) == std::string::npos) continue;
          print(c, run_slide(c));
        }
}

// Single cases for the investigation: GRANFLOW_CONTACT_CASE="contact shape h_mm plan_deg mu level dt settle".
TEST(TerrainContact, OneCase) {
  const char* e = std::getenv("GRANFLOW_CONTACT_CASE");
  if (!e) GTEST_SKIP() << "set GRANFLOW_CONTACT_CASE";
  char contact[16], shape[16];
  double hmm = 20, plan = 0, mu = 0.7, settle = 0.1;
  int level = 0;
  ASSERT_GE(std::sscanf(e, "%15s %15s %lf %lf %lf %d %lf", contact, shape, &hmm, &plan, &mu, &level, &settle), 6);
  Slide c;
  const std::string k = contact;
  c.contact = k == "nodes" ? Terrain::Contact::Nodes : Terrain::Contact::Support;
  c.shape = std::string(shape) == "linear" ? ShapeKind::Linear : ShapeKind::QuadraticBSpline;
  c.h = hmm * 1e-3;
  c.plan_deg = plan;
  c.mu = mu;
  c.level = level != 0;
  c.settle = settle;
  print(c, run_slide(c));
}
