// The time loop on the host: stages, adaptive or fixed step, sampling, outputs, failure stop.
#pragma once

#include <csignal>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <granflow/io/output.hpp>

#include "forces.hpp"
#include "measures.hpp"
#include "output.hpp"
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
  long shortened_steps = 0;  // steps the stable limit shortened below time.dt (since the start or resume)
  double dt_min = std::numeric_limits<double>::infinity();  // the shortest of those
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
  double at_rest_since = -1;  // time.stop_at_rest: the rest window's first sample (< 0: not stopped at rest)
};

// time.stop_at_rest: the time of the first sample of the trailing run of rows[0, settled) whose
// kinetic energy lies below `ratio` times the peak among rows at t >= t_from (the last stage),
// when that run spans at least `hold` seconds; -1 otherwise.
double rest_since(const std::vector<SeriesRow>& rows, size_t settled, double t_from, double ratio, double hold);

RunSummary run(const SceneSetup& su, Runner& runner, const RunOptions& opt);
// Steps to queue in a span (at most cap): fixed step, exactly those up to its end; adaptive, an
// estimate (steps queued past the end do nothing).
long span_length(const Span& s, long cap);

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

}  // namespace granflow::mpm
