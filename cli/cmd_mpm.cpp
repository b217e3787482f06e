// granflow mpm <scene.toml>: run a scene (CPU twin or CUDA) and write VTU/PVD frames, CSV
// series, the final free surface and PNG snapshots; granflow bench mpm: per-phase timings.
#include <chrono>
#include <algorithm>
#include <cstdio>
#include <memory>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>

#include <granflow/mpm/driver.hpp>

#include "commands.hpp"
#include "io/input_error.hpp"
#include "io/parameter_set.hpp"
#include "io/scene.hpp"

namespace granflow::cli {

namespace {

mpm::SceneSetup setup_from_file(const std::string& file) {
  const mpm::Scene sc = io::load_scene(file);
  try {
    return mpm::make_setup(sc);
  } catch (const mpm::SceneError& e) {
    throw io::InputError(io::where(file) + e.what());
  }
}

std::unique_ptr<mpm::Runner> make_runner(const mpm::SceneSetup& su, const std::string& backend) {
  return backend == "cuda" ? mpm::make_cuda_runner(su) : mpm::make_cpu_runner(su);
}

std::string locate_plot_script() {
  for (const std::string& p : {std::string("scripts/plot_mpm.py"), io::data_directory() + "/../scripts/plot_mpm.py"})
    if (std::filesystem::exists(p)) return p;
  return "";
}

struct MpmOptions {
  std::string scene, out, backend = "cpu", png_fields = "p,T,eps_pd";
  bool force = false, no_png = false, quiet = false;
  double stop_after = -1;
};

void run_mpm(const MpmOptions& o) {
  const mpm::SceneSetup su = setup_from_file(o.scene);
  std::string out = o.out;
  if (out.empty()) out = "mpm_out/" + std::filesystem::path(o.scene).stem().string();
  if (std::filesystem::exists(out) && !std::filesystem::is_empty(out) && !o.force)
    throw io::InputError("output directory '" + out + "' exists and is not empty; use --force to overwrite it");
  if (o.force && std::filesystem::exists(out)) {
    for (const auto& e : std::filesystem::directory_iterator(out))
      if (e.is_regular_file()) std::filesystem::remove(e.path());
  }
  auto runner = make_runner(su, o.backend);
  const mpm::Scene& sc = su.scene;
  std::fprintf(stderr, "granflow mpm: %s\n  %ld particles, %ld grid nodes, %s, %s, %s shape functions, %s\n",
               sc.name.c_str(), runner->particles(), runner->nodes(),
               sc.material.model == mpm::ModelKind::PhaseTransition ? "phase-transition model" : "frictional-only model",
               sc.adaptive ? "adaptive dt" : ("dt = " + std::to_string(sc.dt) + " s").c_str(),
               sc.shape == mpm::ShapeKind::Linear ? "linear" : "quadratic B-spline", runner->device().c_str());
  mpm::RunOptions ro;
  ro.out_dir = out;
  ro.progress = !o.quiet;
  ro.stop_after = o.stop_after;
  const mpm::RunSummary s = mpm::run(su, *runner, ro);
  std::printf("scene: %s\nparticles: %ld\nsteps: %ld\nsimulated: %.6g s\nwall: %.3f s\n", sc.name.c_str(),
              runner->particles(), s.steps, s.t_end, s.wall_s);
  std::printf("particle-updates/s: %.4g\n", s.wall_s > 0 ? runner->particles() * double(s.steps) / s.wall_s : 0.0);
  if (s.consolidation.done)
    std::printf("after stage 1: base sigma_v %.1f Pa vs rho g h %.1f Pa; max |sigma_v/(rho g z) - 1| = %.3f "
                "(middle half of the body, below the top cell)\n",
                s.consolidation.base_sigma_v, s.consolidation.base_rho_g_h, s.consolidation.max_rel_error);
  if (s.stats.updates > 0) {
    const double u = double(s.stats.updates);
    std::printf("constitutive updates: %.3g, mean substeps %.2f; substep limit %.3g%%, tension cut-off %.3g%%, "
                "V_s clamped %.3g%%, separated %.3g%%\n",
                u, s.stats.substeps / u, 100 * s.stats.substep_limit / u, 100 * s.stats.tension_cutoff / u,
                100 * s.stats.vs_clamped / u, 100 * s.stats.separated / u);
  }
  std::printf("final run-out: %.4f m\nfinal height: %.4f m\nmax speed: %.4g m/s\n", s.final.runout, s.final.height,
              s.final.max_speed);
  std::printf("output: %s (frames.pvd, runout.csv, tracked.csv, profile_final.csv)\n", out.c_str());
  if (!o.no_png) {
    const std::string script = locate_plot_script();
    if (script.empty()) {
      std::fprintf(stderr, "PNG snapshots skipped: scripts/plot_mpm.py not found\n");
    } else {
      // the system interpreter has the distribution's matplotlib; a pyenv/venv one may not
      const std::string py = std::filesystem::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
      const std::string cmd = py + " '" + script + "' '" + out + "' --fields " + o.png_fields;
      if (std::system(cmd.c_str()) != 0) std::fprintf(stderr, "PNG snapshots skipped: '%s' failed\n", cmd.c_str());
    }
  }
  if (!s.ok) throw std::runtime_error("run stopped: " + s.message);
}

struct BenchOptions {
  std::string scene, backend = "cpu";
  long steps = 200, warmup = 20;
};

void bench_mpm(const BenchOptions& o) {
  const mpm::SceneSetup su = setup_from_file(o.scene);
  auto r = make_runner(su, o.backend);
  const mpm::Scene& sc = su.scene;
  r->set_stage(0, sc.stages[0].damping, sc.stages[0].flip.value_or(sc.flip));
  double dt = sc.adaptive ? std::min(sc.dt, sc.cfl * su.dt_estimate) : sc.dt;
  for (long i = 0; i < o.warmup; ++i) {
    const mpm::StepResult s = r->step(dt, sc.adaptive);
    if (sc.adaptive) dt = std::min(sc.dt, s.dt_limit);
  }
  r->reset_times();
  const auto t0 = std::chrono::steady_clock::now();
  for (long i = 0; i < o.steps; ++i) {
    const mpm::StepResult s = r->step(dt, sc.adaptive);
    if (sc.adaptive) dt = std::min(sc.dt, s.dt_limit);
    if (!s.ok) throw std::runtime_error("benchmark step " + std::to_string(i) + " failed at particle " + std::to_string(s.particle));
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const mpm::PhaseTimes t = r->times();
  std::printf("scene: %s\ndevice: %s\nparticles: %ld\ngrid nodes: %ld\nsteps: %ld (after %ld warm-up)\n",
              sc.name.c_str(), r->device().c_str(), r->particles(), r->nodes(), o.steps, o.warmup);
  std::printf("wall: %.4f s\nparticle-updates/s: %.4g\ntime per step: %.2f us\n", wall,
              r->particles() * double(o.steps) / wall, 1e6 * wall / o.steps);
  std::printf("  P2G:                %.2f us\n  grid update:        %.2f us\n  G2P + constitutive: %.2f us\n",
              1e6 * t.p2g / o.steps, 1e6 * t.grid / o.steps, 1e6 * t.g2p / o.steps);
}

}  // namespace

void register_mpm(CLI::App& app) {
  auto o = std::make_shared<MpmOptions>();
  auto* cmd = app.add_subcommand("mpm", "Run an MPM scene (mpm/scenes/*.toml)");
  cmd->add_option("scene", o->scene, "scene file")->required()->check(CLI::ExistingFile);
  cmd->add_option("--out", o->out, "output directory (default mpm_out/<scene>)");
  cmd->add_flag("--force", o->force, "overwrite an existing output directory");
  cmd->add_option("--backend", o->backend, "cpu (OpenMP twin) or cuda")->check(CLI::IsMember({"cpu", "cuda"}));
  cmd->add_option("--stop-after", o->stop_after, "stop at this simulated time [s] (throughput runs)");
  cmd->add_option("--png-fields", o->png_fields, "fields of the PNG snapshots (comma separated)");
  cmd->add_flag("--no-png", o->no_png, "do not call scripts/plot_mpm.py");
  cmd->add_flag("--quiet", o->quiet, "no progress line");
  cmd->callback([o] { run_mpm(*o); });
}

void register_bench_mpm(CLI::App& bench) {
  auto o = std::make_shared<BenchOptions>();
  auto* cmd = bench.add_subcommand("mpm", "MPM throughput: time per step by phase after warm-up");
  cmd->add_option("scene", o->scene, "scene file")->required()->check(CLI::ExistingFile);
  cmd->add_option("--steps", o->steps, "timed steps")->check(CLI::PositiveNumber);
  cmd->add_option("--warmup", o->warmup, "untimed steps first")->check(CLI::NonNegativeNumber);
  cmd->add_option("--backend", o->backend, "cpu or cuda")->check(CLI::IsMember({"cpu", "cuda"}));
  cmd->callback([o] { bench_mpm(*o); });
}

}  // namespace granflow::cli
