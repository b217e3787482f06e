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

// The CUDA backend's options as given on the command line (name -> value, unset ones empty).
struct CudaFlags {
  std::string graphs, graph_steps, sort, p2g, g2p_block, g2p_regcap;
  mpm::CudaOptions options() const {
    mpm::CudaOptions o;
    const std::pair<const char*, const std::string*> all[] = {{"graphs", &graphs}, {"graph-steps", &graph_steps},
                                                              {"sort", &sort},     {"p2g", &p2g},
                                                              {"g2p-block", &g2p_block}, {"g2p-regcap", &g2p_regcap}};
    for (const auto& [name, value] : all)
      if (!value->empty() && !mpm::set_cuda_option(o, name, *value))
        throw io::InputError(std::string("--") + name + ": invalid value '" + *value + "'");
    return o;
  }
  void add(CLI::App* cmd) {
    cmd->add_option("--graphs", graphs, "CUDA: replay captured chunks of steps as graphs (on|off; default on)");
    cmd->add_option("--graph-steps", graph_steps, "CUDA: longest captured chunk in steps (default 32)");
    cmd->add_option("--sort", sort, "CUDA: reorder particles by cell every N steps (0: never; default 32)");
    cmd->add_option("--p2g", p2g, "CUDA: P2G scatter atomic|warp|tile (default tile)");
    cmd->add_option("--g2p-block", g2p_block, "CUDA: threads per block of G2P + constitutive (default 128)");
    cmd->add_option("--g2p-regcap", g2p_regcap, "CUDA: G2P + constitutive with at most 168 registers (on|off)");
  }
};

std::unique_ptr<mpm::Runner> make_runner(const mpm::SceneSetup& su, const std::string& backend,
                                         const CudaFlags& flags) {
  const mpm::CudaOptions co = flags.options();  // checked for either backend
  return backend == "cuda" ? mpm::make_cuda_runner(su, co) : mpm::make_cpu_runner(su);
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
  long span = 10000;
  CudaFlags cuda;
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
  auto runner = make_runner(su, o.backend, o.cuda);
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
  ro.max_span = o.span;
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
  std::string scene, backend = "cpu", loop = "span";
  long steps = 200, warmup = 20, split = 100;
  CudaFlags cuda;
};

void bench_mpm(const BenchOptions& o) {
  const mpm::SceneSetup su = setup_from_file(o.scene);
  auto r = make_runner(su, o.backend, o.cuda);
  mpm::BenchOptions bo;
  bo.steps = o.steps;
  bo.warmup = o.warmup;
  bo.split_steps = o.split;
  bo.step_by_step = o.loop == "step";
  const mpm::BenchResult b = mpm::bench(su, *r, bo);
  std::fputs(mpm::bench_report(su, *r, bo, b).c_str(), stdout);
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
  cmd->add_option("--span", o->span, "most steps queued without a host round-trip (1: one per step)")
      ->check(CLI::PositiveNumber);
  o->cuda.add(cmd);
  cmd->callback([o] { run_mpm(*o); });
}

void register_bench_mpm(CLI::App& bench) {
  auto o = std::make_shared<BenchOptions>();
  auto* cmd = bench.add_subcommand("mpm", "MPM throughput: time per step by phase after warm-up");
  cmd->add_option("scene", o->scene, "scene file")->required()->check(CLI::ExistingFile);
  cmd->add_option("--steps", o->steps, "timed steps")->check(CLI::PositiveNumber);
  cmd->add_option("--warmup", o->warmup, "untimed steps first")->check(CLI::NonNegativeNumber);
  cmd->add_option("--backend", o->backend, "cpu or cuda")->check(CLI::IsMember({"cpu", "cuda"}));
  cmd->add_option("--loop", o->loop, "span: the timed steps as one span; step: a host round-trip per step")
      ->check(CLI::IsMember({"span", "step"}));
  cmd->add_option("--split", o->split, "steps of the separate timed span for the per-phase split (0: none)")
      ->check(CLI::NonNegativeNumber);
  o->cuda.add(cmd);
  cmd->callback([o] { bench_mpm(*o); });
}

}  // namespace granflow::cli
