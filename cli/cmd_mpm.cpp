// granflow mpm <scene.toml>: run a scene (CPU twin or CUDA) and write VTU/PVD frames, CSV
// series, the final free surface and PNG snapshots; granflow bench mpm: per-phase timings.
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>

#include <granflow/io/raster.hpp>
#include <granflow/mpm/checkpoint.hpp>
#include <granflow/mpm/driver.hpp>
#include <granflow/mpm/memory.hpp>

#include "commands.hpp"
#include "mpm_common.hpp"
#include <granflow/io/input_error.hpp>
#include <granflow/io/output.hpp>
#include <granflow/io/parameter_set.hpp>
#include <granflow/io/run_folder.hpp>
#include <granflow/io/share.hpp>
#include <granflow/mpm/scene_file.hpp>

namespace granflow::cli {

namespace fs = std::filesystem;

mpm::SceneSetup setup_from_file(const std::string& file, const mpm::SceneOverrides& overrides,
                                const std::string& precision) {
  mpm::Scene sc = mpm::load_scene(file, overrides);
  if (!precision.empty()) mpm::parse_precision(precision, sc.precision);
  return mpm::make_setup_for_file(sc);
}

namespace {
// What a checkpoint must have been written for: the scene file's bytes, the parameter set's
// values (as granflow writes them, so comments and layout do not count; --params picks the
// set) and the --set overrides as given.
std::uint64_t scene_hash(const mpm::Scene& sc) {
  auto bytes = [](const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
  };
  std::uint64_t h = mpm::fnv1a(bytes(sc.file));  // and the files it names: terrain raster, base profile
  if (sc.terrain && sc.terrain->raster) h = mpm::fnv1a(bytes(sc.terrain->raster->file), h);
  if (sc.base && !sc.base->file.empty()) h = mpm::fnv1a(bytes(sc.base->file), h);
  std::uint64_t hash = mpm::fnv1a(io::format_parameter_set(io::load_parameter_set(sc.material.name)), h);
  for (int i = 1; i < sc.material_count(); ++i)
    hash = mpm::fnv1a(io::format_parameter_set(io::load_parameter_set(sc.material_at(i).name)), hash);
  for (const auto& a : sc.overrides) hash = mpm::fnv1a("--set " + a, hash);
  return hash;
}
}  // namespace

std::string shell_word(const std::string& w) {
  if (!w.empty() && w.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-+=.,/:@%") ==
                        std::string::npos)
    return w;
  std::string q = "'";
  for (char c : w) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string override_args(const mpm::SceneOverrides& ov) {
  std::string s;
  if (!ov.params.empty()) s += " --params " + shell_word(ov.params);
  for (const auto& a : ov.material_params) s += " --params " + shell_word(a);
  for (const auto& a : ov.sets) s += " --set " + shell_word(a);
  return s;
}

void add_override_options(CLI::App* cmd, mpm::SceneOverrides& ov) {
  // NAME=SET (a [[material]] name, then the set) goes to material_params; a plain SET to params, once
  cmd->add_option_function<std::vector<std::string>>(
         "--params",
         [&ov](const std::vector<std::string>& given) {
           for (const std::string& v : given) mpm::add_params(ov, v);
         },
         "parameter set instead of the scene's material.parameters: a name under data/params or a TOML "
         "file (as granflow element --params); NAME=SET for the [[material]] named NAME (repeatable)")
      ->allow_extra_args(false);
  cmd->add_option("--set", ov.sets,
                  "override one value, KEY=VALUE (repeatable, applied in order). KEY in a parameter set's table "
                  "(frictional., collisional., initial., numerics.) changes the material's set, e.g. "
                  "frictional.phi_c_deg=30 (NAME:frictional.phi_c_deg=30: of the [[material]] named NAME, "
                  "required with two or more; NAME:e0=0.8: a key of its table); any other KEY is a scene key, "
                  "checked as in the file, e.g. "
                  "grid.h=0.0025, time.dt=5e-5, time.adaptive=true, material.model=frictional, "
                  "solver.precision=fp32, stage[1].duration=0.5 ([i]: entry i of an array of tables). VALUE is "
                  "a TOML value; a bare word is a string")
      ->allow_extra_args(false);  // one value per --set: the scene argument is never taken as one
}

// devices > 1: the scene split into slabs along x (docs/mpm_slabs.md).
std::unique_ptr<mpm::Runner> make_runner(const mpm::SceneSetup& su, const std::string& backend,
                                         const CudaFlags& flags, int devices) {
  const mpm::CudaOptions co = flags.options();  // checked for either backend
  if (devices > 1) {
    if (su.members > 1) throw io::InputError("--devices: an ensemble is not split into slabs");
    mpm::SlabOptions so;
    so.slabs = devices;
    if (backend == "cuda" && mpm::cuda_device_count() < devices)
      throw io::InputError("--devices " + std::to_string(devices) + ": this host shows " +
                           std::to_string(mpm::cuda_device_count()) + " CUDA devices");
    try {
      if (backend == "cuda") return mpm::make_cuda_runner(su, co, so);
      return mpm::make_cpu_runner(su, so);
    } catch (const std::invalid_argument& e) {
      throw io::InputError("--devices " + std::to_string(devices) + ": " + e.what());
    }
  }
  return backend == "cuda" ? mpm::make_cuda_runner(su, co) : mpm::make_cpu_runner(su);
}

// What a run split into slabs did (nothing for one slab).
void print_slab_report(const mpm::Runner& r, const mpm::RunSummary& s) {
  const mpm::SlabReport rep = r.slab_report();
  if (rep.slabs < 2) return;
  std::string borders;
  for (size_t i = 1; i + 1 < rep.borders.size(); ++i) borders += (i > 1 ? ", " : "") + std::to_string(rep.borders[i]);
  std::printf("slabs: %d along x, borders at node columns %s at the end; %ld re-partitions moved them (%ld asked "
              "for); %ld points migrated; largest imbalance %.3f; %ld halo nodes exchanged per step; exchange, "
              "migration and re-partitioning %.1f %% of the wall\n",
              rep.slabs, borders.c_str(), rep.repartitions, rep.checks, rep.migrated, rep.max_imbalance,
              rep.halo_nodes, s.wall_s > 0 ? 100.0 * s.times.exchange / s.wall_s : 0.0);
}

void require_backend(const std::string& backend) {
  if (backend != "cuda") return;
  if (const std::string why = mpm::cuda_unavailable_reason(); !why.empty())
    throw io::InputError("--backend cuda: " + why + "; use --backend cpu");
}

std::string locate_script(const std::string& name) {
  return io::script_path(name);
}

volatile std::sig_atomic_t g_signal = 0;
namespace {
volatile std::sig_atomic_t g_deferred = 0;
// The first signal asks the loops to stop; a second stops at once (the default action), unless
// a checkpoint is being written: then it waits for the write (a third does not).
void on_signal(int sig) {
  if (g_signal == 0) {
    g_signal = sig;
    return;
  }
  if (io::critical_write_active() && g_deferred == 0) {
    g_deferred = sig;
    static const char note[] = "\ngranflow: finishing the checkpoint first (once more stops at once)\n";
    [[maybe_unused]] const ssize_t n = ::write(STDERR_FILENO, note, sizeof note - 1);
    return;
  }
  struct sigaction dfl {};
  dfl.sa_handler = SIG_DFL;
  sigemptyset(&dfl.sa_mask);
  ::sigaction(sig, &dfl, nullptr);
  ::raise(sig);
}
}  // namespace

SignalGuard::SignalGuard() {
  g_signal = 0;
  g_deferred = 0;
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  sigaction(SIGINT, &sa, &old_int_);
  sigaction(SIGTERM, &sa, &old_term_);
}
SignalGuard::~SignalGuard() {
  sigaction(SIGINT, &old_int_, nullptr);
  sigaction(SIGTERM, &old_term_, nullptr);
}

namespace {

// Time per step by phase (timed steps) and on the device (spans), and the share of the split
// G2P's plastic pass: the figures that scripts/gpu.sh reads from a run's summary.
void print_step_times(const mpm::RunSummary& s, long particles, const std::string& backend_options) {
  if (s.steps <= 0) return;
  const mpm::PhaseTimes& t = s.times;
  if (t.steps > 0)
    std::printf("kernel time per step: P2G %.2f us, grid %.2f us, G2P + constitutive %.2f us; wall per step %.2f us\n",
                1e6 * t.p2g / t.steps, 1e6 * t.grid / t.steps, 1e6 * t.g2p / t.steps, 1e6 * s.wall_s / s.steps);
  if (t.span_steps > 0)
    std::printf("device time per step (spans): %.2f us; wall per step %.2f us; %s\n", 1e6 * t.device / t.span_steps,
                1e6 * s.wall_s / s.steps, backend_options.c_str());
  if (t.deferred > 0)
    std::printf("plastic returns (second G2P pass): %.1f %% of the updates\n", 100.0 * t.deferred_share(particles));
}

struct MpmOptions {
  std::string scene, out, backend = "cpu", png_fields = "p,T,eps_pd", precision;
  bool force = false, no_png = false, quiet = false, restart = false;
  double stop_after = -1;
  double checkpoint_every = -1;  // > 0 overrides output.checkpoint_dt
  long span = 10000;
  int devices = 1;
  CudaFlags cuda;
  mpm::SceneOverrides overrides;
};

// --restart: the checkpoint in `out`, read and checked against the scene (input errors).
mpm::Checkpoint load_restart(const std::string& out, const mpm::SceneSetup& su, std::uint64_t hash) {
  std::error_code ec;
  const std::string path = out + "/" + mpm::kCheckpointFile;
  if (!fs::exists(path, ec))
    throw io::InputError(io::where(path) +
                         "no checkpoint to restart from (one is written every output.checkpoint_dt or "
                         "--checkpoint-every seconds of simulated time and when a run is interrupted; a run that "
                         "completed removes it)");
  try {
    mpm::Checkpoint c = mpm::read_checkpoint(path);
    mpm::check_checkpoint(c, su, hash);
    return c;
  } catch (const mpm::CheckpointError& e) {
    throw io::InputError(io::where(path) + e.what());
  }
}

// The command that continues this run from its checkpoint.
std::string restart_command(const MpmOptions& o, const std::string& out) {
  std::string again = "granflow mpm " + o.scene + " --out " + out + " --restart" + override_args(o.overrides);
  if (o.backend != "cpu") again += " --backend " + o.backend;
  if (o.devices > 1) again += " --devices " + std::to_string(o.devices);
  if (!o.precision.empty()) again += " --precision " + o.precision;
  if (o.checkpoint_every > 0) {
    std::ostringstream os;
    os << " --checkpoint-every " << o.checkpoint_every;
    again += os.str();
  }
  return again;
}

void run_mpm(const MpmOptions& o) {
  using Clock = std::chrono::steady_clock;
  const auto t_start = Clock::now();
  auto since = [](Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); };
  require_backend(o.backend);
  const mpm::SceneSetup su = setup_from_file(o.scene, o.overrides, o.precision);
  std::string out = o.out;
  if (out.empty()) out = "mpm_out/" + fs::path(o.scene).stem().string();
  std::uint64_t hash = scene_hash(su.scene);
  // a checkpoint resumes in the precision it was written in (fp64 hashes as before)
  if (su.scene.precision != mpm::Precision::FP64)
    hash = mpm::fnv1a(std::string("precision ") + mpm::precision_name(su.scene.precision), hash);
  // The output folder: locked for this run; --force empties only a granflow run folder,
  // --restart keeps only what its checkpoint lists.
  if (o.restart && o.force)
    throw io::InputError("--restart continues the run in '" + out +
                         "' and --force would delete it first: give one of them");
  io::RunFolder folder(out, o.restart ? io::FolderUse::Restart : o.force ? io::FolderUse::Force : io::FolderUse::Fresh,
                       mpm::kCheckpointFile);
  std::optional<mpm::Checkpoint> resume;
  if (o.restart) {
    resume = load_restart(out, su, hash);
    folder.keep_only(mpm::checkpoint_outputs(*resume));
  }
  auto runner = make_runner(su, o.backend, o.cuda, o.devices);
  const mpm::Scene& sc = su.scene;
  std::fprintf(stderr, "granflow mpm: %s\n  %ld particles, %ld grid nodes, %s, %s, %s shape functions, %s\n",
               sc.name.c_str(), runner->particles(), runner->nodes(),
               sc.material.model == mpm::ModelKind::PhaseTransition ? "phase-transition model" : "frictional-only model",
               sc.adaptive ? "adaptive dt" : ("dt = " + std::to_string(sc.dt) + " s").c_str(),
               sc.shape == mpm::ShapeKind::Linear ? "linear" : "quadratic B-spline", runner->device().c_str());
  std::fprintf(stderr, "  precision %s; %s\n", mpm::precision_name(sc.precision), mpm::memory_line(su).c_str());
  if (sc.terrain) {
    if (sc.terrain->mu)
      std::fprintf(stderr, "  terrain %s: Coulomb mu = %g on %zu nodes near the ground, deeper nodes held\n",
                   sc.terrain->raster->file.c_str(), *sc.terrain->mu, su.terrain.size());
    else
      std::fprintf(stderr, "  terrain %s: no-slip\n", sc.terrain->raster->file.c_str());
  }
  if (sc.material_count() > 1) {  // per material: its set, points and mass
    std::vector<long> points(sc.material_count(), 0);
    std::vector<double> mass(sc.material_count(), 0.0);
    for (long i = 0; i < su.particles.n; ++i) {
      ++points[su.point_material[i]];
      mass[su.point_material[i]] += su.particles.m[i];
    }
    for (int m = 0; m < sc.material_count(); ++m) {
      const mpm::Material& mm = sc.material_at(m);
      std::fprintf(stderr, "  material %s: %s, rho_p %g, e0 %g, phi_c %.4g deg; %ld points, mass %.6g kg%s\n",
                   mm.label.c_str(), mm.name.c_str(), mm.params.c.rho_p, mm.e0, mm.params.f.phi_c * 180 / M_PI,
                   points[m], mass[m], sc.dim == 2 ? " per m" : "");
    }
  }
  for (size_t b = 0; b < sc.bodies.size() && b < su.seeded_volume.size(); ++b)
    if (sc.bodies[b].is_release())  // seeded on the lattice against the surfaces' volume
      std::fprintf(stderr, "  body[%zu]: seeded volume %.6g m^3, between the surfaces %.6g m^3 (%+.2f %%)\n", b,
                   su.seeded_volume[b], su.geometric_volume[b],
                   su.geometric_volume[b] > 0 ? 100 * (su.seeded_volume[b] / su.geometric_volume[b] - 1) : 0.0);
    else if (sc.bodies[b].is_mesh())  // against the mesh's own volume (docs/mpm_meshes.md)
      std::fprintf(stderr, "  body[%zu]: seeded volume %.6g m^3, the mesh's own %.6g m^3 (%+.2f %%)\n", b,
                   su.seeded_volume[b], su.geometric_volume[b],
                   su.geometric_volume[b] > 0 ? 100 * (su.seeded_volume[b] / su.geometric_volume[b] - 1) : 0.0);
  if (resume)
    std::fprintf(stderr, "  restarting at t = %.6g s (step %ld) from %s/%s\n", resume->loop.t, resume->loop.step,
                 out.c_str(), mpm::kCheckpointFile);
  mpm::RunOptions ro;
  ro.out_dir = out;
  ro.progress = !o.quiet;
  ro.stop_after = o.stop_after;
  ro.max_span = o.span;
  ro.checkpoint_dt = o.checkpoint_every > 0 ? o.checkpoint_every : sc.output.checkpoint_dt;
  ro.scene_hash = hash;
  ro.resume = resume ? &*resume : nullptr;
  ro.interrupt = &g_signal;
  mpm::RunSummary s;
  const double before_run_s = since(t_start);
  const auto t_run = Clock::now();
  try {
    SignalGuard guard;
    s = mpm::run(su, *runner, ro);
  } catch (const io::OutputError& e) {
    std::error_code ec;
    const bool ck = fs::exists(out + "/" + mpm::kCheckpointFile, ec);
    throw io::OutputError(std::string(e.what()) + (ck ? "; when that is fixed, continue with: " + restart_command(o, out)
                                                     : "; when that is fixed, run it again with --force"),
                          e.os_error());
  }
  if (s.interrupted) {
    const int sig = s.interrupted;
    const std::string again = restart_command(o, out);
    std::fprintf(stderr,
                 "granflow: interrupted by %s at t = %.6g s (step %ld); wrote the checkpoint %s and the series so far "
                 "(runout.csv, tracked.csv); continue with: %s\n",
                 sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : ("signal " + std::to_string(sig)).c_str(),
                 s.t_end, s.steps, s.checkpoint.c_str(), again.c_str());
    throw ExitStatus{128 + sig};
  }
  const double run_s = since(t_run);
  const auto t_after = Clock::now();
  std::printf("scene: %s\nparticles: %ld\nsteps: %ld\nsimulated: %.6g s\nwall: %.3f s\n", sc.name.c_str(),
              runner->particles(), s.steps, s.t_end, s.wall_s);
  if (s.at_rest_since >= 0)
    std::printf("at rest: kinetic energy below %g of its peak from t = %.6g s for %g s (time.stop_at_rest, "
                "time.rest_hold): ended at t = %.6g s of %.6g s\n",
                sc.stop_at_rest, s.at_rest_since, sc.rest_hold, s.t_end, sc.duration());
  if (!sc.adaptive && s.shortened_steps > 0)
    std::printf("time.dt: %ld steps shortened to the stable step (time.cap_to_stable: CFL 1 of the P-wave and "
                "particle speeds); the shortest %.4g s against %.4g s\n",
                s.shortened_steps, s.dt_min, sc.dt);
  std::printf("precision: %s\n", mpm::precision_name(sc.precision));
  std::printf("particle-updates/s: %.4g\n", s.wall_s > 0 ? runner->particles() * double(s.steps) / s.wall_s : 0.0);
  print_step_times(s, runner->particles(), o.backend == "cuda" ? mpm::describe(o.cuda.options()) : "CPU twin");
  print_slab_report(*runner, s);
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
    if (s.stats.warps > 0) {
      char per_step[80] = "";  // CUDA keeps no per-step largest count (steps = 0)
      if (s.stats.steps > 0)
        std::snprintf(per_step, sizeof per_step, "; mean over steps of the step's largest %.2f", s.stats.mean_step_max());
      std::printf("substeps of one update: largest %ld; mean over 32-point groups (a GPU warp) of their largest %.2f%s\n",
                  s.stats.max_substeps, s.stats.mean_warp_max(), per_step);
    }
    print_plastic_returns(s.stats);
  }
  std::printf("final run-out: %.4f m\nfinal height: %.4f m\nmax speed: %.4g m/s\n", s.final.runout, s.final.height,
              s.final.max_speed);
  const int nmat = sc.material_count();  // the last sample's measures per material (materials.csv)
  if (nmat > 1 && !s.series.empty() && s.material_series.size() == static_cast<size_t>(nmat) * s.series.size())
    for (int k = 0; k < nmat; ++k) {
      const mpm::Measures& m = s.material_series[(s.series.size() - 1) * nmat + k];
      std::printf("material %s: final run-out %.4f m, final height %.4f m, max speed %.4g m/s\n",
                  sc.material_at(k).label.c_str(), m.runout, m.height, m.max_speed);
    }
  for (const mpm::ForcePeak& f : s.forces)
    std::printf("force on %s: peak %.4g %s (mean over %g s) at t = %.4g s, impulse %.4g %s; largest single step %.4g %s\n",
                f.boundary.c_str(), f.peak, sc.dim == 2 ? "N/m" : "N", sc.output.series_dt, f.t_peak, f.impulse,
                sc.dim == 2 ? "N s/m" : "N s", f.step_peak, sc.dim == 2 ? "N/m" : "N");
  if (s.forces.size() > 1)
    std::printf("forces: a node two boundaries hold counts for the first of the obstacles, the walls (each in scene "
                "order), the base, the terrain: a floor between walls misses what its corner nodes carry "
                "(docs/mpm_obstacles.md)\n");
  std::printf("output: %s (frames.pvd, runout.csv, tracked.csv, profile_final.csv%s%s%s)\n", out.c_str(),
              sc.dim == 3 && sc.terrain ? ", deposit.csv, maps/" : "",
              s.forces.empty() ? "" : (sc.obstacles.empty() ? ", obstacle_forces.csv" : ", obstacle_forces.csv, obstacles.vtu"),
              sc.gauges.empty() ? "" : ", gauges.csv");
  if (g_signal != 0) {
    std::fprintf(stderr, "PNG snapshots skipped: interrupted after the run had completed\n");
  } else if (!o.no_png) {
    // the system interpreter has the distribution's matplotlib; a pyenv/venv one may not
    const std::string py = std::filesystem::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
    const std::string script = locate_script("plot_mpm.py");
    if (script.empty()) {
      std::fprintf(stderr, "PNG snapshots skipped: scripts/plot_mpm.py not found\n");
    } else {
      const std::string cmd = py + " '" + script + "' '" + out + "' --fields " + o.png_fields;
      if (std::system(cmd.c_str()) != 0) {
        std::error_code ec;
        fs::remove_all(out + "/png", ec);  // what it left is not a finished set of snapshots
        std::fprintf(stderr, "PNG snapshots skipped: '%s' failed\n", cmd.c_str());
      }
    }
    if (sc.dim == 3 && sc.terrain && fs::exists(out + "/maps/terrain.asc")) {  // the maps over a hillshade
      const std::string maps_script = locate_script("plot_maps.py");
      if (maps_script.empty()) {
        std::fprintf(stderr, "map PNGs skipped: scripts/plot_maps.py not found\n");
      } else {
        const std::string cmd = py + " '" + maps_script + "' '" + out + "'";
        if (std::system(cmd.c_str()) != 0) {
          std::error_code ec;
          for (const char* m : {"deposit_thickness", "max_speed", "max_depth"})
            fs::remove(out + "/png/map_" + std::string(m) + ".png", ec);
          std::fprintf(stderr, "map PNGs skipped: '%s' failed\n", cmd.c_str());
        }
      }
    }
  }
  // the manifest, last: the folder is complete (or stopped by --stop-after, or failed, as it says)
  std::ostringstream status;
  status.precision(8);
  if (!s.ok)
    status << "failed: " << s.message;
  else if (s.t_end < sc.duration() * (1 - 1e-12))
    status << "stopped at t = " << s.t_end << " s (--stop-after)"
           << (s.checkpoint.empty() ? "" : "; --restart continues from the checkpoint");
  else
    status << "complete";
  folder.complete(status.str());
  // Host time around the steps (the process's start and teardown are outside this line): on the
  // GPU the run's own share is its wall less the spans' device time (frames, samples, the loop).
  std::printf("host time: before the run %.2f s (scene, particles, runner), after it %.2f s (outputs, PNGs, manifest)",
              before_run_s, since(t_after));
  if (s.times.span_steps > 0)
    std::printf("; in the run outside the spans %.2f s (run %.2f s less device %.2f s)", run_s - s.times.device, run_s,
                s.times.device);
  std::printf("; in the loop: full frames %.2f s, handing frames to the writer %.2f s, waiting for it %.2f s, samples %.2f s\n",
              s.host.full_frames, s.host.frame_handover, s.host.writer_wait, s.host.samples);
  if (!s.ok) throw std::runtime_error("run stopped: " + s.message);
}

struct BenchOptions {
  std::string scene, backend = "cpu", loop = "span", precision;
  long steps = 200, warmup = 20, split = 100;
  int devices = 1;
  CudaFlags cuda;
  mpm::SceneOverrides overrides;
};

void bench_mpm(const BenchOptions& o) {
  using Clock = std::chrono::steady_clock;
  require_backend(o.backend);
  const auto t_setup = Clock::now();
  const mpm::SceneSetup su = setup_from_file(o.scene, o.overrides, o.precision);
  const double setup_s = std::chrono::duration<double>(Clock::now() - t_setup).count();
  const auto t_runner = Clock::now();
  auto r = make_runner(su, o.backend, o.cuda, o.devices);
  const double runner_s = std::chrono::duration<double>(Clock::now() - t_runner).count();
  mpm::BenchOptions bo;
  bo.steps = o.steps;
  bo.warmup = o.warmup;
  bo.split_steps = o.split;
  bo.step_by_step = o.loop == "step";
  const mpm::BenchResult b = mpm::bench(su, *r, bo);
  std::fputs(mpm::bench_report(su, *r, bo, b).c_str(), stdout);
  std::printf("precision: %s\n%s\nset-up: %.2f s (scene and particles), %.2f s (runner, upload)\n",
              mpm::precision_name(su.scene.precision), mpm::memory_line(su).c_str(), setup_s, runner_s);
}

}  // namespace

void register_mpm(CLI::App& app) {
  auto o = std::make_shared<MpmOptions>();
  auto* cmd = app.add_subcommand("mpm", "Run an MPM scene (mpm/scenes/*.toml)");
  cmd->add_option("scene", o->scene, "scene file")->required()->check(CLI::ExistingFile);
  cmd->add_option("--out", o->out, "output directory (default mpm_out/<scene>)");
  cmd->add_flag("--force", o->force, "replace the output folder of an earlier granflow run (one with a manifest, checkpoint or stale lock); any other folder is refused");
  cmd->add_option("--backend", o->backend, "cpu (OpenMP twin) or cuda")->check(CLI::IsMember({"cpu", "cuda"}));
  cmd->add_option("--stop-after", o->stop_after, "stop at this simulated time [s] (throughput runs)");
  cmd->add_option("--checkpoint-every", o->checkpoint_every,
                  "write a checkpoint every T seconds of simulated time (overrides output.checkpoint_dt)")
      ->check(CLI::Validator(
          [](std::string& v) {
            double x = 0;
            std::istringstream is(v);
            return (is >> x) && is.eof() && x > 0 && std::isfinite(x)
                       ? std::string()
                       : "must be a number of seconds > 0, got '" + v + "'";
          },
          "SECONDS > 0"));
  cmd->add_flag("--restart", o->restart, "continue the run in --out from its checkpoint");
  cmd->add_option("--png-fields", o->png_fields, "fields of the PNG snapshots (comma separated)");
  cmd->add_option("--precision", o->precision, "fp64, mixed or fp32: overrides the scene's solver.precision")
      ->check(CLI::IsMember({"fp64", "mixed", "fp32"}));
  add_override_options(cmd, o->overrides);
  cmd->add_flag("--no-png", o->no_png, "do not call scripts/plot_mpm.py (nor plot_maps.py)");
  cmd->add_flag("--quiet", o->quiet, "no progress line");
  cmd->add_option("--span", o->span, "most steps queued without a host round-trip (1: one per step)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--devices", o->devices,
                  "split the scene into N slabs along x, one per device (docs/mpm_slabs.md); the CPU twin runs "
                  "them in this process")
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
  cmd->add_option("--precision", o->precision, "fp64, mixed or fp32: overrides the scene's solver.precision")
      ->check(CLI::IsMember({"fp64", "mixed", "fp32"}));
  add_override_options(cmd, o->overrides);
  cmd->add_option("--devices", o->devices, "split the scene into N slabs along x (docs/mpm_slabs.md)")
      ->check(CLI::PositiveNumber);
  o->cuda.add(cmd);
  cmd->callback([o] { bench_mpm(*o); });
}

void print_plastic_returns(const mpm::UpdateStats& u) {
  if (u.plastic == 0) return;
  const double np = double(u.plastic);
  double sum = 0;
  for (int e = 0; e < mpm::kCostBins; ++e) sum += double(e) * u.plastic_evaluations[e];
  auto quantile = [&](double q) {
    long acc = 0;
    for (int e = 0; e < mpm::kCostBins; ++e)
      if ((acc += u.plastic_evaluations[e]) >= q * np) return e;
    return mpm::kCostBins - 1;
  };
  long slow_groups = 0, slow_points = 0, groups = 0;
  for (int k = 0; k < 33; ++k) {
    groups += u.slow_in_group[k];
    if (k > 0) slow_groups += u.slow_in_group[k], slow_points += k * u.slow_in_group[k];
  }
  std::printf("plastic returns: %.2f %% of the updates; residual evaluations mean %.2f, median %d, 90 %% %d, "
              "99 %% %d (%d+ counts as %d); halving trials %.3f per return; floored %.3f %%, bracketed %.3f %%; "
              "32-point groups with a slow point (>= %d evaluations) %.2f %%, holding %.2f slow points each\n",
              100 * np / double(u.updates), sum / np, quantile(0.5), quantile(0.9), quantile(0.99),
              mpm::kCostBins - 1, mpm::kCostBins - 1, u.halvings / np, 100 * u.floored / np,
              100 * u.bracketed / np, mpm::kSlowEvaluations, groups ? 100.0 * slow_groups / groups : 0.0,
              slow_groups ? double(slow_points) / slow_groups : 0.0);
}

}  // namespace granflow::cli
