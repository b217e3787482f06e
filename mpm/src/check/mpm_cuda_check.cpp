// GPU against CPU twin on the CI column collapse (built in code: no TOML reader on the GPU
// machine). Exits 77 ("no CUDA device") where there is no GPU, so ctest marks it skipped.
// Besides run-out and height (0.5 %), every particle's final position is compared in the
// original order (the GPU reorders particles by cell; at most 10 % may lie h/4 apart), and a run that fails (a block falling
// out of the grid) must report a particle of the same row at the same step, give or take 2.
// A case whose CPU result itself moves by more than 0.5 % under round-off (volumetric
// averaging: perturbing the initial positions by 1e-13 relative spreads its run-out over
// 0.65 %) is compared with an ensemble of such perturbed CPU runs: the GPU must lie within the
// ensemble's range widened by 0.5 %. Two cases add a frictional floor and a gate lifted during
// the collapse (the contact grid kernel, and the step's time in graphs and spans).
// Ensemble runs (ensemble.hpp: 4 members of the column differing in phi_c and e0; one case also
// in floor friction and gate speed): the GPU ensemble against the CPU twin's ensemble and each
// member against the GPU single run of its scene, with the same tolerances; a member thrown out
// of the grid must fail alone, at the step of the CPU twin (give or take 2), and leave the
// others as their single runs. --ensembles runs these cases only; --short shortens the collapse.
// Terrain (3D builds, GRANFLOW_MPM_CUDA_3D): a slab sliding with Coulomb friction down a planar
// raster dipping 30 deg towards 30 deg off x (the terrain pass, terrain_kernel), same tolerances.
// Several materials: the column as two layers of different sands (also without walls), and in
// 3D builds two blocks of different sands on the terrain, GPU against the CPU twin;
// --materials runs these cases only.
// Slabs (cuda_slabs.cuh): the CI column (2D, 2 and 3 slabs, fp64 and fp32), the low wall with its
// forces, the 3D low box and pier and the terrain slide, each split along x with and without
// forced re-partitions, against the CPU twin with the same tolerances, and points must have
// crossed a border; --slabs runs these only.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <memory>
#include <optional>
#include <stdexcept>

#include <granflow/io/raster.hpp>
#include <granflow/mpm/driver.hpp>
#include <granflow/mpm/ensemble.hpp>
#include <granflow/mpm/kernels.hpp>

using namespace granflow::mpm;

namespace {

// Multiplies every coordinate by 1 + 1e-13 u, u uniform in [-1, 1] (xorshift, seeded).
void perturb_positions(SceneSetup& su, unsigned long long seed) {
  unsigned long long r = 88172645463325252ull ^ (seed * 0x9E3779B97F4A7C15ull);
  for (double& x : su.particles.x) {
    r ^= r << 13;
    r ^= r >> 7;
    r ^= r << 17;
    x *= 1.0 + 1e-13 * (static_cast<double>(r % 2001) / 1000.0 - 1.0);
  }
}

struct Range {
  double lo = 1e300, hi = -1e300;
  void add(double v) { lo = std::min(lo, v); hi = std::max(hi, v); }
  bool holds(double v, double tol) const { return v >= lo * (1 - tol) && v <= hi * (1 + tol); }
};

// CUDA options other than the defaults, as the cases spell them.
CudaOptions cuda_options(const char* s) {
  CudaOptions co;
  if (std::strstr(s, "sort 0,")) co.sort_every = 0;
  if (std::strstr(s, "sort 1,")) co.sort_every = 1;
  if (std::strstr(s, "sort 32,")) co.sort_every = 32;
  if (std::strstr(s, "p2g tile")) co.p2g = CudaOptions::P2G::Tile;
  if (std::strstr(s, "sort 7,")) co.sort_every = 7;
  if (std::strstr(s, "p2g warp")) co.p2g = CudaOptions::P2G::Warp;
  if (std::strstr(s, "p2g atomic")) co.p2g = CudaOptions::P2G::Atomic;
  if (std::strstr(s, "graphs off")) co.graphs = false;
  if (std::strstr(s, "g2p-regcap on")) co.g2p_reg_cap = true;
  if (std::strstr(s, "graph-steps 4")) co.graph_steps = 4;
  if (std::strstr(s, "g2p-split on")) co.g2p_split = CudaOptions::Split::On;
  if (std::strstr(s, "g2p-split off")) co.g2p_split = CudaOptions::Split::Off;
  return co;
}

// ---- ensembles -------------------------------------------------------------------------------

// Steps of a fixed-step span from t to t_until, landing on t_land, at most cap (as the driver's
// span_length counts them).
long fixed_steps(double t, double dt, double t_land, double t_until, long cap) {
  long n = 0;
  while (n < cap) {
    t += span_step_size(t, dt, t_land);
    ++n;
    if (span_reached(t, t_until)) break;
  }
  return n;
}

struct MemberFail {
  MemberFailure f;
  long step = 0;  // the step it failed in (1: the first)
};

struct Drive {
  bool ok = true;  // no failure that no member owns
  std::string message;
  long steps = 0;
  double wall_s = 0;
  std::vector<MemberFail> failed;
  HostParticles at_failure;  // the state right after the last retirement
};

// The scene's stages with its fixed step, in spans up to each stage's end (no samples: the same
// steps for every runner). A failed span retires the members that failed in its last step; the
// others took that step, so the ensemble goes on from its end. A failure no member owns (a
// single run) stops the run.
Drive drive(const SceneSetup& su, Runner& r) {
  const auto w0 = std::chrono::steady_clock::now();
  const Scene& sc = su.scene;
  Drive out;
  double t = 0, t_end = 0;
  for (size_t si = 0; si < sc.stages.size() && out.ok; ++si) {
    const Stage& st = sc.stages[si];
    r.set_stage(static_cast<int>(si), st.damping, st.flip.value_or(sc.flip));
    t_end += st.duration;
    while (t < t_end - 1e-12 * t_end) {
      Span s;
      s.t = t;
      s.dt = sc.dt;
      s.t_land = t_end;
      s.t_until = t_end - 1e-12 * t_end;
      s.max_steps = fixed_steps(s.t, s.dt, s.t_land, s.t_until, 10000);
      const SpanResult res = r.advance_span(s);
      out.steps += res.steps;
      if (res.ok) {
        t = res.t;
        continue;
      }
      const std::vector<MemberFailure> f = r.retire_failed_members();
      if (f.empty()) {
        out.ok = false;
        out.message = "particle " + std::to_string(res.particle) + " at step " + std::to_string(out.steps) + ": " +
                      status_field(res.status);
        break;
      }
      for (const MemberFailure& m : f) out.failed.push_back({m, out.steps});
      if (!r.retire_failed_members().empty()) {
        out.ok = false;
        out.message = "a second retire_failed_members() returned members again";
        break;
      }
      r.download(out.at_failure);
      t = res.t + res.h_last;
    }
  }
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count();
  return out;
}

struct Agreement {
  double runout = 0, height = 0;  // relative differences
  long far = 0;                   // points more than h/4 apart (original order)
  double ra = 0, rb = 0;          // the run-outs
};

// Two frames of one member's scene (positions in the original order).
Agreement agree(const Frame& a, const Frame& b, const SceneSetup& su) {
  Agreement g;
  const Measures ma = measure(a, su, su.particles.m), mb = measure(b, su, su.particles.m);
  g.ra = ma.runout;
  g.rb = mb.runout;
  g.runout = std::fabs(mb.runout - ma.runout) / ma.runout;
  g.height = std::fabs(mb.height - ma.height) / ma.height;
  const long n = a.n;
  for (long i = 0; i < n; ++i)
    if (std::hypot(a.x[i] - b.x[i], a.x[n + i] - b.x[n + i]) > 0.25 * su.scene.h) ++g.far;
  return g;
}

struct EnsembleCase {
  ModelKind model;
  ShapeKind shape;
  Precision precision;
  const char* cuda;          // CUDA options other than the defaults
  bool boundaries = false;   // floor friction and lifted gate, per member
  bool vol_avg = false;      // volumetric averaging: 0.1 s of collapse (round-off grows later)
  int failing = -1;          // this member is thrown upwards out of the grid
};

constexpr int kEnsembleMembers = 4;

// Member k: phi_c + k degrees, e0 - 0.01 k; with boundaries a floor of mu 0.3 + 0.1 k and the
// gate lifted at 0.8 + 0.2 k m/s in the collapse. The failing member's points start at 3 m/s
// upwards: they leave the grid after about 600 steps (CPU twin: step 594, in the consolidation).
SceneSetup member_setup(const EnsembleCase& c, int k, bool short_run) {
  Scene sc = small_column_scene(c.model, c.shape);
  sc.precision = c.precision;
  sc.volumetric_averaging = c.vol_avg;
  sc.material.params.f.phi_c += k * M_PI / 180;
  sc.material.e0 -= 0.01 * k;
  if (c.boundaries) {
    sc.walls[2].mu = 0.3 + 0.1 * k;
    sc.stages[1].gate = sc.stages[0].gate;
    sc.stages[1].gate->lift_speed = 0.8 + 0.2 * k;
  }
  if (short_run || c.vol_avg) sc.stages.back().duration = 0.1;
  SceneSetup su = make_setup(sc);
  if (k == c.failing)
    for (long i = 0; i < su.particles.n; ++i) su.particles.v[su.particles.n + i] = 3.0;
  return su;
}

// One ensemble case; prints a line per case and per member, returns whether it passed.
bool ensemble_case(const EnsembleCase& c, bool short_run, double tol) {
  std::vector<SceneSetup> ms;
  for (int k = 0; k < kEnsembleMembers; ++k) ms.push_back(member_setup(c, k, short_run));
  const SceneSetup en = make_ensemble_setup(ms);
  const long np = ms[0].particles.n;
  const CudaOptions co = cuda_options(c.cuda);
  auto cpu = make_cpu_runner(en);
  auto gpu = make_cuda_runner(en, co);
  const Drive dc = drive(en, *cpu);
  const Drive dg = drive(en, *gpu);
  Frame fc, fg;
  cpu->frame(fc, false);
  gpu->frame(fg, false);
  HostParticles hg;
  gpu->download(hg);
  bool ok = dc.ok && dg.ok && gpu->nodes() == kEnsembleMembers * ms[0].n_nodes &&
            gpu->particles() == kEnsembleMembers * np;
  std::string lines;
  double single_wall = 0;
  Agreement worst_cpu, worst_single;
  char buf[1024];
  for (int k = 0; k < kEnsembleMembers; ++k) {
    auto single = make_cuda_runner(ms[k], co);
    const Drive ds = drive(ms[k], *single);
    single_wall += ds.wall_s;
    Frame fs;
    single->frame(fs, false);
    const Frame ck = member_frame(fc, k, np), gk = member_frame(fg, k, np);
    auto fail_of = [k](const Drive& d) -> const MemberFail* {
      for (const MemberFail& f : d.failed)
        if (f.f.member == k) return &f;
      return nullptr;
    };
    const MemberFail* fcpu = fail_of(dc);
    const MemberFail* fgpu = fail_of(dg);
    if (k != c.failing) {
      const Agreement a = agree(ck, gk, ms[k]), b = agree(fs, gk, ms[k]);
      const bool mok = !fcpu && !fgpu && ds.ok && a.runout <= tol && a.height <= tol && a.far <= np / 10 &&
                       b.runout <= tol && b.height <= tol && b.far <= np / 10;
      ok = ok && mok;
      worst_cpu.runout = std::max(worst_cpu.runout, a.runout);
      worst_cpu.height = std::max(worst_cpu.height, a.height);
      worst_cpu.far = std::max(worst_cpu.far, a.far);
      worst_single.runout = std::max(worst_single.runout, b.runout);
      worst_single.height = std::max(worst_single.height, b.height);
      worst_single.far = std::max(worst_single.far, b.far);
      std::snprintf(buf, sizeof buf,
                    "  member %d: run-out cpu ensemble %.5f m, gpu ensemble %.5f m, gpu single %.5f m | vs cpu: %.2e / "
                    "%.2e, %ld points > h/4 | vs single: %.2e / %.2e, %ld points%s%s\n",
                    k, a.ra, a.rb, b.ra, a.runout, a.height, a.far, b.runout, b.height, b.far,
                    mok ? "" : "  <- differs", ds.ok ? "" : ("; single run: " + ds.message).c_str());
    } else {
      // fails alone, at the CPU twin's step (give or take 2) with a particle of the same row,
      // as its single run does; its points stay where the failed step left them
      const long n = en.particles.n;
      const bool same = fcpu && fgpu && std::labs(fcpu->step - fgpu->step) <= 2 &&
                        std::fabs(en.particles.x[n + fcpu->f.particle] - en.particles.x[n + fgpu->f.particle]) < 1e-9;
      const bool single_too = !ds.ok && fgpu && std::labs(ds.steps - fgpu->step) <= 2;
      bool frozen = fgpu && dg.at_failure.n == n;
      for (long i = k * np; frozen && i < (k + 1) * np; ++i)
        frozen = hg.x[i] == dg.at_failure.x[i] && hg.x[n + i] == dg.at_failure.x[n + i];
      const bool mok = same && single_too && frozen && dc.failed.size() == 1 && dg.failed.size() == 1;
      ok = ok && mok;
      std::snprintf(buf, sizeof buf,
                    "  member %d (thrown out of the grid): cpu ensemble step %ld particle %ld (%s) | gpu ensemble step "
                    "%ld particle %ld (%s) | gpu single: %s | retired points unchanged since: %s%s\n",
                    k, fcpu ? fcpu->step : -1L, fcpu ? fcpu->f.particle : -1L,
                    fcpu ? status_field(fcpu->f.status) : "-",
                    fgpu ? fgpu->step : -1L, fgpu ? fgpu->f.particle : -1L, fgpu ? status_field(fgpu->f.status) : "-",
                    ds.ok ? "did not fail" : ds.message.c_str(), frozen ? "yes" : "no", mok ? "" : "  <- differs");
    }
    lines += buf;
  }
  std::printf("ensemble of %d: %-44s %-9s %-5s %s%s%s | cpu %.2f s, gpu %.2f s, %d gpu single runs %.2f s | worst "
              "rel. diff vs cpu %.2e / %.2e, vs single %.2e / %.2e %s\n",
              kEnsembleMembers, en.scene.name.c_str(), c.shape == ShapeKind::Linear ? "linear" : "quadratic",
              precision_name(c.precision), c.vol_avg ? "vol-avg " : "", c.boundaries ? "floor mu, gate speed " : "",
              c.cuda, dc.wall_s, dg.wall_s, kEnsembleMembers, single_wall, worst_cpu.runout, worst_cpu.height,
              worst_single.runout, worst_single.height, ok ? "OK" : "FAIL");
  std::fputs(lines.c_str(), stdout);
  if (!dc.ok) std::printf("  cpu: %s\n", dc.message.c_str());
  if (!dg.ok) std::printf("  gpu: %s\n", dg.message.c_str());
  return ok;
}

// A raster in memory: elevation z(easting, northing) at the cell centres.
std::shared_ptr<const granflow::io::Raster> plane_raster(double west, double cell, long n, double dip, double azimuth,
                                                         double thick) {
  auto r = std::make_shared<granflow::io::Raster>();
  r->file = "memory";
  r->ncols = r->nrows = n;
  r->west = r->south = west;
  r->cellsize = cell;
  for (long row = 0; row < n; ++row)
    for (long col = 0; col < n; ++col)
      r->values.push_back(thick - std::tan(dip) * (r->centre_east(col) * std::cos(azimuth) +
                                                   r->centre_north(row) * std::sin(azimuth)));
  return r;
}

// The slab of Terrain.BlockOnATiltedRasterSlidesAtTheCoulombRate (tests/mpm): 4 cm thick between
// the terrain and the surface above it, mu 0.2, 0.25 s (784 points, 20 mm grid).
Scene terrain_slide_scene(double duration) {
  Scene sc = small_column_scene(ModelKind::Frictional);
  sc.name = "slab on a 30 deg raster, mu 0.2 (terrain pass)";
  sc.material = flume_scene(0.04, 1e-4, ModelKind::Frictional, ShapeKind::Linear, 0.1).material;
  sc.dim = 3;
  sc.origin = {0.0, 0.0, 0.0};
  sc.size = {0.5, 0.48, 0.5};
  sc.h = 0.02;
  sc.dt = 2e-4;
  sc.gravity = {0.0, -9.81, 0.0};
  sc.walls.clear();
  sc.tracks.clear();
  sc.runout_x.clear();
  sc.runout_y.clear();
  sc.output.times.clear();
  Stage s;
  s.name = "slide";
  s.duration = duration;
  sc.stages = {s};
  const double deg = M_PI / 180;
  Terrain t;
  t.origin = {0.0, 0.0, -0.46};
  t.mu = 0.2;
  t.raster = plane_raster(-0.05, 0.05, 12, 30 * deg, 30 * deg, 0.0);
  sc.terrain = t;
  Body b;
  b.top = plane_raster(-0.05, 0.05, 12, 30 * deg, 30 * deg, 0.04);
  b.plan_x = {0.06, 0.2, 0.2, 0.06};
  b.plan_z = {0.06, 0.06, 0.2, 0.2};
  sc.bodies = {b};
  return sc;
}

// One scene over several GPUs (cuda_slabs.cuh): while g_split.slabs > 1 the cases run their GPU
// side split into slabs along x, slab s on device s % (visible devices) (on one GPU every slab
// shares it and runs the same exchange and migration code), and must have migrated points.
SlabOptions g_split;

std::unique_ptr<Runner> gpu_runner(const SceneSetup& su, const char* cuda) {
  if (g_split.slabs > 1) return make_cuda_runner(su, cuda_options(cuda), g_split);
  return make_cuda_runner(su, cuda_options(cuda));
}

// Runs a set-up on the CPU twin and on `gpu`, prints one line (`head`: the case's name and
// switches; `tail` before the verdict) and returns whether they agree: run-out and height within
// tol, at most a tenth of the points more than h/4 from their twin.
bool agrees_with_twin(const SceneSetup& su, Runner& gpu, const std::string& head, const std::string& tail,
                      double tol) {
  RunOptions opt;
  opt.progress = false;
  auto cpu = make_cpu_runner(su);
  const RunSummary a = run(su, *cpu, opt);
  const RunSummary b = run(su, gpu, opt);
  HostParticles ha, hb;
  cpu->download(ha);
  gpu.download(hb);
  long far = 0;
  for (long i = 0; i < ha.n; ++i) {
    double d2 = 0;
    for (int d = 0; d < su.scene.dim; ++d) d2 += std::pow(ha.x[d * ha.n + i] - hb.x[d * ha.n + i], 2);
    if (std::sqrt(d2) > 0.25 * su.scene.h) ++far;
  }
  const double rel = std::fabs(b.final.runout - a.final.runout) / a.final.runout;
  const double relh = std::fabs(b.final.height - a.final.height) / a.final.height;
  bool ok = a.ok && b.ok && rel <= tol && relh <= tol && far <= ha.n / 10;
  std::string split;
  if (const SlabReport rep = gpu.slab_report(); rep.slabs > 1) {
    char buf[200];
    std::snprintf(buf, sizeof buf, " | %d slabs: %ld points migrated, %ld re-partitions (%ld asked for)", rep.slabs,
                  rep.migrated, rep.repartitions, rep.checks);
    split = buf;
    ok = ok && rep.migrated > 0 && (g_split.every == 0 || rep.checks > 0);
  }
  // boundary forces (output.forces): each boundary's impulse within 1e-3 of the twin's
  std::string forces;
  if (!a.forces.empty() && a.forces.size() == b.forces.size()) {
    double worst = 0;
    for (size_t k = 0; k < a.forces.size(); ++k) {
      const double d = std::fabs(b.forces[k].impulse - a.forces[k].impulse) / std::max(a.forces[k].impulse, 1e-12);
      worst = std::max(worst, d);
      char buf[160];
      std::snprintf(buf, sizeof buf, " | %s impulse %.5g / %.5g N s/m", a.forces[k].boundary.c_str(),
                    a.forces[k].impulse, b.forces[k].impulse);
      forces += buf;
    }
    ok = ok && worst <= 1e-3;
    forces += " (rel. diff " + std::to_string(worst) + ")";
  } else if (a.forces.size() != b.forces.size()) {
    ok = false;
    forces = " | the back ends report different boundaries";
  }
  std::printf("%s cpu run-out %.5f m height %.5f m (%.2f s) | gpu run-out %.5f m height %.5f m (%.2f s, %s) | "
              "rel. diff %.2e / %.2e | %ld of %ld points > h/4 apart%s%s%s %s\n",
              head.c_str(), a.final.runout, a.final.height, a.wall_s, b.final.runout, b.final.height, b.wall_s,
              b.device.c_str(), rel, relh, far, ha.n, forces.c_str(), split.c_str(), tail.c_str(), ok ? "OK" : "FAIL");
  if (!a.ok) std::printf("  cpu: %s\n", a.message.c_str());
  if (!b.ok) std::printf("  gpu: %s\n", b.message.c_str());
  return ok;
}

std::string padded(const char* fmt, const std::string& a, const char* b, const char* c = nullptr) {
  char buf[256];
  if (c) std::snprintf(buf, sizeof buf, fmt, a.c_str(), b, c); else std::snprintf(buf, sizeof buf, fmt, a.c_str(), b);
  return buf;
}

// The CUDA runner of a 3D set-up, or null (a line saying so) where the 3D kernels are not compiled.
std::unique_ptr<Runner> cuda_runner_or_skip(const SceneSetup& su, const char* cuda, const std::string& name) {
  try {
    return gpu_runner(su, cuda);
  } catch (const std::runtime_error& e) {
    if (!std::strstr(e.what(), "3D CUDA kernels are not compiled")) throw;
    std::printf("%s: skipped (%s)\n", name.c_str(), e.what());
    return nullptr;
  }
}

// A 3D case on both back ends (agrees_with_twin); skipped (true) where the 3D CUDA kernels are
// not compiled.
bool agrees_with_twin_3d(const SceneSetup& su, ShapeKind shape, const char* cuda, double tol) {
  const std::unique_ptr<Runner> gpu = cuda_runner_or_skip(su, cuda, su.scene.name);
  if (!gpu) return true;
  const char* shape_name = shape == ShapeKind::Linear ? "linear" : "quadratic";
  return agrees_with_twin(su, *gpu, padded("%-55s %-9s %s", su.scene.name, shape_name, cuda), "", tol);
}

// The terrain slide on both back ends: run-out, height and every particle's final position.
// Skipped (true) where the 3D CUDA kernels are not compiled.
bool terrain_case(const char* cuda, bool short_run, double tol) {
  const Scene sc = terrain_slide_scene(short_run ? 0.1 : 0.25);
  const SceneSetup su = make_setup(sc);
  const std::unique_ptr<Runner> gpu = cuda_runner_or_skip(su, cuda, sc.name);
  if (!gpu) return true;
  return agrees_with_twin(su, *gpu, padded("%-55s %s", sc.name, cuda),
                          ", " + std::to_string(su.terrain.size()) + " terrain nodes", tol);
}

// ---- obstacles ----------------------------------------------------------------------------------
// The CI column runs into a low wall (an obstacle 3 cm thick and 4 cm high, 2 cm beyond the
// column, no-slip or frictional): run-out, height and every boundary's impulse (the obstacle,
// the walls; output.forces) on both back ends.
bool obstacle_case(ModelKind model, ShapeKind shape, std::optional<double> mu, const char* cuda, bool short_run,
                   double tol) {
  Scene sc = small_column_scene(model, shape);
  Obstacle o;
  o.name = "low wall";
  o.key = "obstacle[0]";
  o.kind = "box";
  o.poly_x = {0.22, 0.25, 0.25, 0.22};
  o.poly_y = {0.0, 0.0, 0.04, 0.04};
  o.mu = mu;
  sc.obstacles = {o};
  sc.name += mu ? ", low wall mu " + std::to_string(*mu).substr(0, 4) : ", low wall";
  if (short_run) sc.stages.back().duration = 0.1;
  const SceneSetup su = make_setup(sc);
  auto gpu = gpu_runner(su, cuda);
  const char* shape_name = shape == ShapeKind::Linear ? "linear" : "quadratic";
  return agrees_with_twin(su, *gpu, padded("%-55s %-9s %s", sc.name, shape_name, cuda), "", tol);
}

// The CI column on both back ends (agrees_with_twin), in the given precision.
bool column_case(ModelKind model, ShapeKind shape, Precision precision, const char* cuda, bool short_run, double tol) {
  Scene sc = small_column_scene(model, shape);
  sc.precision = precision;
  if (precision != Precision::FP64) sc.name += std::string(", ") + precision_name(precision);
  if (short_run) sc.stages.back().duration = 0.1;
  const SceneSetup su = make_setup(sc);
  auto gpu = gpu_runner(su, cuda);
  const char* shape_name = shape == ShapeKind::Linear ? "linear" : "quadratic";
  return agrees_with_twin(su, *gpu, padded("%-55s %-9s %s", sc.name, shape_name, cuda), "", tol);
}

// 3D (GRANFLOW_MPM_CUDA_3D; skipped, true, without it): the CI column as a slab 8 cm wide
// between free-slip side walls, released at once, into a low box (no-slip) and a pier (mu 0.3):
// every boundary's impulse on both back ends, as above. mesh: the low box as a triangle mesh
// (obstacle kind "mesh", the 12 triangles its STL would hold, built here: the GPU machine's
// build has no mesh reader) with mu 0.3, its nodes and normals from the mesh geometry.
bool obstacle_3d_case(ModelKind model, ShapeKind shape, const char* cuda, bool short_run, double tol, bool mesh = false) {
  Scene sc = slab_3d_scene(model, shape, short_run ? 0.1 : 0.25);
  sc.name += mesh ? ", 3D slab, low box as a mesh and pier" : ", 3D slab, low box and pier";
  Obstacle box;
  box.name = "low box";
  box.key = "obstacle[0]";
  box.kind = "box";
  box.shape = Obstacle::Shape::Box;
  box.box_min = {0.21, 0.0, 0.0};  // reached within the short run's 0.1 s
  box.box_max = {0.24, 0.03, 0.04};
  if (mesh) {
    auto m = std::make_shared<TriMesh>();
    m->file = "low box (in memory)";
    for (int v = 0; v < 8; ++v)  // vertex v: x from bit 0, y from bit 1, z from bit 2
      for (int d = 0; d < 3; ++d) m->xyz.push_back((v >> d & 1) ? box.box_max[d] : box.box_min[d]);
    m->tri = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,  // x-, x+, y-
              2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};  // y+, z-, z+ (outward)
    box.kind = "mesh";
    box.shape = Obstacle::Shape::Mesh;
    box.mesh = m;
    box.mu = 0.3;
  }
  Obstacle pier = pier_obstacle("pier", "obstacle[1]", {0.27, 0.06}, 0.02, 0.0, 0.06);
  pier.mu = 0.3;
  sc.obstacles = {box, pier};
  return agrees_with_twin_3d(make_setup(sc), shape, cuda, tol);
}

// ---- several materials -------------------------------------------------------------------------
// The CI column as two layers (issue 34): the lower 4 cm a looser, weaker sand (e0 + 0.03,
// phi_c - 4 deg, rho_p 2500), the rest as before; the GPU (the kMembers kernels with a material
// index per slot, sorted with the points) against the CPU twin, same tolerances.
// no_walls: no wall or gate (the kMembers kernels with masks that hold nothing): the layered
// block, 10 cm off the grid's sides and 8 cm above its bottom (grid 25 cm high), falls for 0.07 s.
bool materials_case(ModelKind model, ShapeKind shape, const char* cuda, bool short_run, double tol,
                    bool no_walls = false) {
  Scene sc = small_column_scene(model, shape);
  sc.name += no_walls ? ", two layers, no walls" : ", two layers";
  sc.material.label = "upper";
  Material lower = sc.material;
  lower.label = "lower";
  lower.e0 += 0.03;
  lower.params.f.phi_c -= 4 * M_PI / 180;
  lower.params.c.rho_p = 2500;
  sc.other_materials = {lower};
  Body b0 = sc.bodies[0], b1 = sc.bodies[0];
  b0.box_max[1] = 0.04;
  b0.material = 1;
  b1.box_min[1] = 0.04;
  if (no_walls) {
    sc.walls.clear();
    for (Body* b : {&b0, &b1})
      for (int d = 0; d < 2; ++d) {
        b->box_min[d] += d == 0 ? 0.1 : 0.08;
        b->box_max[d] += d == 0 ? 0.1 : 0.08;
      }
    for (Stage& st : sc.stages) st.gate.reset();
    sc.size[1] = 0.25;
    sc.stages[0].duration = 0.02;
    sc.stages[1].duration = 0.05;
  }
  sc.bodies = {b0, b1};
  if (short_run && !no_walls) sc.stages.back().duration = 0.1;
  const SceneSetup su = make_setup(sc);
  auto gpu = make_cuda_runner(su, cuda_options(cuda));
  const char* shape_name = shape == ShapeKind::Linear ? "linear" : "quadratic";
  return agrees_with_twin(su, *gpu, padded("%-55s %-9s %s", sc.name, shape_name, cuda), "", tol);
}

// 3D (GRANFLOW_MPM_CUDA_3D; skipped, true, without it): the terrain slide of terrain_case as
// two blocks side by side, the downhill one (x > 0.13 m) a looser, weaker sand (e0 + 0.03,
// phi_c - 4 deg, rho_p 2650): the 3D kMembers kernels (fp64) with the terrain pass, GPU against
// the CPU twin, same tolerances; in fp32 and mixed the twin runs the same precision.
bool materials_3d_case(ModelKind model, ShapeKind shape, const char* cuda, bool short_run, double tol,
                       Precision precision = Precision::FP64) {
  Scene sc = terrain_slide_scene(short_run ? 0.1 : 0.25);
  sc.name = "terrain slide, two materials side by side";
  sc.precision = precision;
  if (precision != Precision::FP64) sc.name += std::string(", ") + precision_name(precision);
  sc.shape = shape;
  if (shape == ShapeKind::QuadraticBSpline) sc.transfer = Scene::Transfer::TaylorPic;
  sc.material = flume_scene(0.04, 1e-4, model, ShapeKind::Linear, 0.1).material;
  sc.material.label = "uphill";
  Material down = sc.material;
  down.label = "downhill";
  down.e0 += 0.03;
  down.params.f.phi_c -= 4 * M_PI / 180;
  down.params.c.rho_p = 2650;
  sc.other_materials = {down};
  Body b0 = sc.bodies[0], b1 = sc.bodies[0];
  b0.plan_x = {0.06, 0.13, 0.13, 0.06};
  b1.plan_x = {0.13, 0.2, 0.2, 0.13};
  b1.material = 1;
  sc.bodies = {b0, b1};
  return agrees_with_twin_3d(make_setup(sc), shape, cuda, tol);
}

}  // namespace

int main(int argc, char** argv) {
  if (!cuda_backend_available()) {
    std::printf("no CUDA device\n");
    return 77;
  }
  const double tol = 0.005;
  int fails = 0;
  struct Case {
    ModelKind model;
    ShapeKind shape;
    bool vol_avg;
    const char* cuda;  // CUDA options other than the defaults
    bool boundaries = false;  // frictional floor (mu 0.4) and a gate lifted at 1 m/s (boundary.hpp)
  };
  const Case cases[] = {{ModelKind::PhaseTransition, ShapeKind::Linear, false, ""},
                        {ModelKind::PhaseTransition, ShapeKind::QuadraticBSpline, false, ""},
                        {ModelKind::Frictional, ShapeKind::Linear, false, ""},
                        {ModelKind::Frictional, ShapeKind::QuadraticBSpline, false, ""},
                        {ModelKind::PhaseTransition, ShapeKind::Linear, true, ""},
                        {ModelKind::PhaseTransition, ShapeKind::QuadraticBSpline, false, "sort 0, p2g atomic"},
                        {ModelKind::PhaseTransition, ShapeKind::QuadraticBSpline, false, "sort 1, p2g warp, graphs off"},
                        {ModelKind::PhaseTransition, ShapeKind::QuadraticBSpline, false, "sort 32, p2g tile, graphs off"},
                        {ModelKind::Frictional, ShapeKind::QuadraticBSpline, false, "sort 7, g2p-regcap on, graph-steps 4"},
                        {ModelKind::PhaseTransition, ShapeKind::QuadraticBSpline, false, "g2p-split on"},
                        {ModelKind::Frictional, ShapeKind::Linear, false, "g2p-split on, g2p-regcap on, sort 0, p2g atomic"},
                        {ModelKind::PhaseTransition, ShapeKind::QuadraticBSpline, false, "", true},
                        {ModelKind::Frictional, ShapeKind::Linear, false, "graphs off", true}};
  // --short: 0.1 s of collapse; --ensembles: the ensemble cases only (e.g. under compute-sanitizer)
  // --materials: the cases of several materials only; --obstacles: the obstacle cases only
  // --slabs: the cases of one scene split over GPUs only; --meshes: the mesh obstacle cases only
  bool short_run = false, ensembles_only = false, materials_only = false, obstacles_only = false, slabs_only = false;
  bool meshes_only = false;
  for (int i = 1; i < argc; ++i) {
    meshes_only = meshes_only || std::strcmp(argv[i], "--meshes") == 0;
    slabs_only = slabs_only || std::strcmp(argv[i], "--slabs") == 0;
    short_run = short_run || std::strcmp(argv[i], "--short") == 0;
    ensembles_only = ensembles_only || std::strcmp(argv[i], "--ensembles") == 0;
    materials_only = materials_only || std::strcmp(argv[i], "--materials") == 0;
    obstacles_only = obstacles_only || std::strcmp(argv[i], "--obstacles") == 0;
  }
  if (meshes_only) {
    fails += obstacle_3d_case(ModelKind::Frictional, ShapeKind::Linear, "", short_run, tol, true) ? 0 : 1;
    fails += obstacle_3d_case(ModelKind::PhaseTransition, ShapeKind::QuadraticBSpline, "sort 1, graphs off", short_run, tol, true) ? 0 : 1;
    return fails == 0 ? 0 : 1;
  }
  if (!ensembles_only && !obstacles_only && !materials_only) {
    using MK = ModelKind;
    using SK = ShapeKind;
    auto split = [&](int slabs, long every) {
      g_split = SlabOptions{};
      g_split.slabs = slabs;
      g_split.every = every;
      for (int s = 0; s < slabs; ++s) g_split.devices.push_back(s % cuda_device_count());
    };
    std::printf("one scene over %d visible GPU(s), split into slabs:\n", cuda_device_count());
    split(2, 0);
    fails += column_case(MK::Frictional, SK::QuadraticBSpline, Precision::FP32, "g2p-split on", short_run, tol) ? 0 : 1;
    split(3, 0);
    fails += column_case(MK::PhaseTransition, SK::Linear, Precision::FP64, "", short_run, tol) ? 0 : 1;
    split(3, 40);
    fails += column_case(MK::PhaseTransition, SK::QuadraticBSpline, Precision::FP64, "sort 1", short_run, tol) ? 0 : 1;
    split(2, 25);
    fails += obstacle_case(MK::Frictional, SK::QuadraticBSpline, 0.3, "", short_run, tol) ? 0 : 1;
    split(3, 0);
    fails += obstacle_3d_case(MK::PhaseTransition, SK::QuadraticBSpline, "", short_run, tol) ? 0 : 1;
    split(2, 30);
    fails += terrain_case("", short_run, tol) ? 0 : 1;
    g_split = SlabOptions{};
    std::printf("one scene on one GPU:\n");
  }
  if (slabs_only) return fails == 0 ? 0 : 1;
  if (!ensembles_only && !obstacles_only) {
    fails += materials_case(ModelKind::PhaseTransition, ShapeKind::Linear, "", short_run, tol) ? 0 : 1;
    fails += materials_case(ModelKind::Frictional, ShapeKind::QuadraticBSpline, "sort 1, graphs off", short_run, tol) ? 0 : 1;
    fails += materials_case(ModelKind::PhaseTransition, ShapeKind::QuadraticBSpline, "sort 7, g2p-split on", short_run, tol) ? 0 : 1;
    fails += materials_case(ModelKind::Frictional, ShapeKind::Linear, "", short_run, tol, true) ? 0 : 1;
    fails += materials_3d_case(ModelKind::Frictional, ShapeKind::Linear, "", short_run, tol) ? 0 : 1;
    fails += materials_3d_case(ModelKind::PhaseTransition, ShapeKind::QuadraticBSpline, "sort 1, graphs off", short_run, tol) ? 0 : 1;
    fails += materials_3d_case(ModelKind::Frictional, ShapeKind::QuadraticBSpline, "", short_run, tol, Precision::FP32) ? 0 : 1;
    fails += materials_3d_case(ModelKind::PhaseTransition, ShapeKind::Linear, "", short_run, tol, Precision::Mixed) ? 0 : 1;
  }
  if (materials_only) return fails == 0 ? 0 : 1;
  if (!ensembles_only) {
    fails += obstacle_case(ModelKind::PhaseTransition, ShapeKind::Linear, std::nullopt, "", short_run, tol) ? 0 : 1;
    fails += obstacle_case(ModelKind::Frictional, ShapeKind::QuadraticBSpline, 0.3, "sort 1, graphs off", short_run, tol) ? 0 : 1;
    fails += obstacle_3d_case(ModelKind::Frictional, ShapeKind::Linear, "", short_run, tol) ? 0 : 1;
    fails += obstacle_3d_case(ModelKind::PhaseTransition, ShapeKind::QuadraticBSpline, "sort 1, graphs off", short_run, tol) ? 0 : 1;
    fails += obstacle_3d_case(ModelKind::Frictional, ShapeKind::QuadraticBSpline, "", short_run, tol, true) ? 0 : 1;
  }
  if (obstacles_only) return fails == 0 ? 0 : 1;
  for (const Case& c : cases) {
    if (ensembles_only) break;
    const CudaOptions co = cuda_options(c.cuda);
    Scene sc = small_column_scene(c.model, c.shape);
    sc.volumetric_averaging = c.vol_avg;
    if (c.boundaries) {
      sc.walls[2].mu = 0.4;  // the floor
      sc.stages[1].gate = sc.stages[0].gate;
      sc.stages[1].gate->lift_speed = 1.0;
      sc.name += ", floor mu 0.4, gate lifted at 1 m/s";
    }
    if (short_run) sc.stages.back().duration = 0.1;
    const SceneSetup su = make_setup(sc);
    RunOptions opt;
    opt.progress = false;
    auto cpu = make_cpu_runner(su);
    auto gpu = make_cuda_runner(su, co);
    const RunSummary a = run(su, *cpu, opt);
    const RunSummary b = run(su, *gpu, opt);
    const double rel = std::fabs(b.final.runout - a.final.runout) / a.final.runout;
    const double relh = std::fabs(b.final.height - a.final.height) / a.final.height;
    // particles in the original order: positions agree (a wrong order would scramble nearly
    // all of them; round-off grown in the collapse moves a few points near the front)
    HostParticles ha, hb;
    cpu->download(ha);
    gpu->download(hb);
    long far = 0;
    for (long i = 0; i < ha.n; ++i)
      if (std::hypot(ha.x[i] - hb.x[i], ha.x[ha.n + i] - hb.x[ha.n + i]) > 0.25 * sc.h) ++far;
    const bool order_ok = far <= ha.n / 10;
    bool ok = a.ok && b.ok && rel <= tol && relh <= tol && order_ok;
    std::string ensemble;
    if (c.vol_avg) {
      Range ro, ht;
      ro.add(a.final.runout);
      ht.add(a.final.height);
      const int runs = 6;
      for (int k = 1; k <= runs; ++k) {
        SceneSetup sp = su;
        perturb_positions(sp, k);
        auto r = make_cpu_runner(sp);
        const RunSummary e = run(sp, *r, opt);
        if (!e.ok) continue;
        ro.add(e.final.runout);
        ht.add(e.final.height);
      }
      ok = a.ok && b.ok && order_ok && ro.holds(b.final.runout, tol) && ht.holds(b.final.height, tol);
      char buf[200];
      std::snprintf(buf, sizeof buf, " | CPU round-off ensemble of %d: run-out %.5f-%.5f m, height %.5f-%.5f m",
                    runs + 1, ro.lo, ro.hi, ht.lo, ht.hi);
      ensemble = buf;
    }
    std::printf("%-55s %-9s %s%s cpu run-out %.5f m height %.5f m (%.2f s) | gpu run-out %.5f m height %.5f m "
                "(%.2f s, %s) | rel. diff %.2e / %.2e | %ld of %ld points > h/4 apart%s %s\n",
                sc.name.c_str(), c.shape == ShapeKind::Linear ? "linear" : "quadratic", c.vol_avg ? "vol-avg " : "",
                c.cuda, a.final.runout, a.final.height, a.wall_s, b.final.runout, b.final.height, b.wall_s,
                b.device.c_str(), rel, relh, far, ha.n, ensemble.c_str(), ok ? "OK" : "FAIL");
    if (!a.ok) std::printf("  cpu: %s\n", a.message.c_str());
    if (!b.ok) std::printf("  gpu: %s\n", b.message.c_str());
    fails += ok ? 0 : 1;
  }
  if (!ensembles_only)
    for (const char* cuda : {"", "sort 1, p2g atomic, graphs off"}) fails += terrain_case(cuda, short_run, tol) ? 0 : 1;
  if (!ensembles_only) {
    // a falling block leaves the grid: the first bad particle and the step, in the original order
    Scene sc = small_column_scene(ModelKind::PhaseTransition, ShapeKind::QuadraticBSpline);
    sc.walls.clear();
    for (auto& st : sc.stages) st.gate.reset();
    const SceneSetup su = make_setup(sc);
    RunOptions opt;
    opt.progress = false;
    auto cpu = make_cpu_runner(su);
    auto gpu = make_cuda_runner(su);
    const RunSummary a = run(su, *cpu, opt);
    const RunSummary b = run(su, *gpu, opt);
    long pa = -1, pb = -1, sa = -1, sb = -1;
    auto parse = [](const std::string& m, long& p, long& s) {
      std::sscanf(m.c_str(), "particle %ld", &p);
      const size_t k = m.find("at step ");
      if (k != std::string::npos) std::sscanf(m.c_str() + k, "at step %ld", &s);
    };
    parse(a.message, pa, sa);
    parse(b.message, pb, sb);
    const long n = su.particles.n;
    const bool ok = !a.ok && !b.ok && pa >= 0 && pb >= 0 && pb < n && std::labs(sa - sb) <= 2 &&
                    std::fabs(su.particles.x[n + pa] - su.particles.x[n + pb]) < 1e-9;
    std::printf("falling block: cpu particle %ld step %ld | gpu particle %ld step %ld %s\n  cpu: %s\n  gpu: %s\n", pa,
                sa, pb, sb, ok ? "OK" : "FAIL", a.message.c_str(), b.message.c_str());
    fails += ok ? 0 : 1;
  }
  {
    using MK = ModelKind;
    using SK = ShapeKind;
    using PR = Precision;
    const EnsembleCase ens[] = {{MK::PhaseTransition, SK::Linear, PR::FP64, ""},
                                {MK::Frictional, SK::Linear, PR::FP64, "g2p-split on"},
                                {MK::PhaseTransition, SK::Linear, PR::FP32, "sort 1, p2g atomic, graphs off"},
                                {MK::Frictional, SK::Linear, PR::FP32, ""},
                                {MK::PhaseTransition, SK::QuadraticBSpline, PR::FP64, "p2g tile", true},
                                {MK::Frictional, SK::QuadraticBSpline, PR::Mixed, "sort 7, graph-steps 4"},
                                {MK::PhaseTransition, SK::Linear, PR::FP64, "", false, true},
                                {MK::PhaseTransition, SK::Linear, PR::FP64, "", false, false, 2}};
    for (const EnsembleCase& c : ens) fails += ensemble_case(c, short_run, tol) ? 0 : 1;
  }
  return fails == 0 ? 0 : 1;
}
