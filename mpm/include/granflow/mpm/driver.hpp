// The time loop on the host: stages, adaptive or fixed step, sampling, outputs, failure stop.
#pragma once

#include <csignal>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <granflow/io/output.hpp>

#include "forces.hpp"
#include "runner.hpp"

namespace granflow::mpm {

struct Checkpoint;  // checkpoint.hpp

struct RunOptions {
  std::string out_dir;    // empty: write nothing (tests)
  bool progress = true;   // progress line on stderr
  double stop_after = -1; // > 0: stop at this simulated time (short CPU throughput runs)
  // Checkpoints (out_dir/checkpoint.bin, needs out_dir): every checkpoint_dt of simulated time
  // (<= 0: only when interrupted); removed when the scene's last stage is done.
  double checkpoint_dt = 0;
  std::uint64_t scene_hash = 0;          // stored in checkpoints (see check_checkpoint)
  const Checkpoint* resume = nullptr;    // continue from this state (checked by the caller)
  // Polled after every step; non-zero (a signal number): checkpoint, write the CSVs, stop.
  const volatile std::sig_atomic_t* interrupt = nullptr;
  long max_span = 10000;  // most steps queued without a host round-trip (1: one per step)
};

// Run-out and height of a frame, measured along the scene's run-out polyline.
struct Measures {
  double runout = 0, height = 0, max_speed = 0, kinetic_energy = 0, mean_T = 0, max_T = 0;
};
// material >= 0: of that material's points only (su.point_material), for scenes of several.
Measures measure(const Frame& fr, const SceneSetup& su, const std::vector<double>& mass, int material = -1);
// Of the runs of consecutive bins of positive weight, the one of the largest total weight (the
// first of equal ones): its first and last bin; {0, -1} when every bin is empty. The run-out's
// deposit (point counts) and a gauge's flow (mass) are such runs.
std::pair<long, long> heaviest_run(const std::vector<double>& weight);
// Free surface: for bins of one grid cell along x, the highest particle top (x, y).
std::vector<std::pair<double, double>> free_surface(const Frame& fr, const SceneSetup& su);

struct SeriesRow {
  double t, t_flow;
  int stage;
  Measures m;
};
struct TrackRow {
  double t, t_flow;
  size_t track;
  double x, y, vx, vy, p, q, eps_pd, T, eta_c, K_col;
};

// One sample of a gauge (Scene::gauges): the contiguous run of points along the line that holds
// the most mass, within width/2 of it. depth: its extent along the line; u: the mass-weighted
// velocity across the line (positive to the right of from -> to), u_along: along it; density:
// its mass over depth x width; mass_flux: rho h u [kg/(m s)]. All zero where no point is near.
struct GaugeRow {
  double t, t_flow;
  size_t gauge;
  double depth, u, u_along, density, mass_flux;
  long points;
};
std::vector<GaugeRow> measure_gauges(const Frame& fr, const SceneSetup& su, const std::vector<double>& mass,
                                     double t, double t_flow);
// dir/gauges.csv (written only for a scene with gauges).
void write_gauges_csv(const std::string& dir, const Scene& sc, const std::vector<GaugeRow>& rows);

// Vertical stress against rho g depth at the end of the first stage, away from the walls.
struct ConsolidationCheck {
  bool done = false;
  double max_rel_error = 0;      // over depth bins below the top layer, middle half of the body
  double base_sigma_v = 0, base_rho_g_h = 0;
};

// From a full frame at the end of the first stage.
ConsolidationCheck check_consolidation(const Frame& fr, const SceneSetup& su);

// Host seconds of the time loop outside the steps (granflow mpm's `host time` line): full frames
// gathered (device to host, diagnostics), frames handed to the writer (the copy), waits for
// the writer (before checkpoints and at the end) and the samples' main-thread part.
struct HostTimes {
  double full_frames = 0, frame_handover = 0, writer_wait = 0, samples = 0;
};

struct RunSummary {
  bool ok = true;
  std::string message;
  long steps = 0;
  double t_end = 0;
  double wall_s = 0;
  Measures final;
  std::vector<SeriesRow> series;
  std::vector<TrackRow> tracks;
  ConsolidationCheck consolidation;
  PhaseTimes times;
  HostTimes host;
  UpdateStats stats;
  std::string device;
  int interrupted = 0;     // the interrupt value that stopped the run (0: not interrupted)
  std::string checkpoint;  // the checkpoint written last (empty: none, or removed at the end)
  std::vector<ForcePeak> forces;  // per boundary with force probes (output.forces)
  std::vector<ForceRow> force_rows;  // obstacle_forces.csv's rows
  std::vector<GaugeRow> gauges;      // gauges.csv's rows
  // Scenes of several materials: per series row, each material's measures (row-major;
  // materials.csv). Empty otherwise, and in ensembles.
  std::vector<Measures> material_series;
};

RunSummary run(const SceneSetup& su, Runner& runner, const RunOptions& opt);
// Steps to queue in a span (at most cap): fixed step, exactly those up to its end; adaptive, an
// estimate (steps queued past the end do nothing).
long span_length(const Span& s, long cap);

// The CSVs a run writes: dir/runout.csv and dir/tracked.csv (docs/mpm.md lists the columns),
// and a free surface (x, surface_y).
void write_series_csv(const std::string& dir, const Scene& sc, const std::vector<SeriesRow>& series,
                      const std::vector<TrackRow>& tracks);
void write_profile_csv(const std::string& path, const std::vector<std::pair<double, double>>& surface);

// Throughput of the first stage after a warm-up (granflow bench mpm).
// The timed steps run as one span (or step by step, a host round-trip each: the old loop);
// the per-phase split comes from a separate timed span where the backend does not time its
// production spans (CUDA: events around each phase and a synchronisation per step).
struct BenchOptions {
  long steps = 200, warmup = 20;
  bool step_by_step = false;
  long split_steps = 100;  // steps of the separate timed span (0: none)
};
struct BenchResult {
  long steps = 0;
  double wall_s = 0;
  PhaseTimes run;    // of the timed steps (CUDA: device time only)
  PhaseTimes split;  // per-phase times (CPU: of the timed steps)
};
BenchResult bench(const SceneSetup& su, Runner& runner, const BenchOptions& opt);
// The figures as printed by both commands (scene, device, options, times per step).
std::string bench_report(const SceneSetup& su, const Runner& runner, const BenchOptions& opt, const BenchResult& r);

// Writers, through io::AtomicFile: a file appears under its name only complete; a failure
// (io::OutputError) leaves the previous file.
// `fields`: the point arrays besides position (scene.hpp frame_field_names); empty: all.
// FrameFormat::Raw writes the arrays from the frame's vectors in pieces, with no whole copy.
void write_vtu(const std::string& path, const Frame& fr, FrameFormat format, const std::vector<std::string>& fields = {},
               io::Durability durability = io::Durability::Buffered);
void write_pvd(const std::string& path, const std::vector<std::pair<double, std::string>>& frames);

}  // namespace granflow::mpm
