// Ensembles: N members of one scene that differ in material parameters, initial state, wall
// and base friction or gate speed, advanced together by one runner (kernels.hpp, Members) in
// the same loops and kernel launches (docs/mpm_ensembles.md).
#pragma once

#include <csignal>
#include <string>
#include <vector>

#include "driver.hpp"
#include "runner.hpp"

namespace granflow::mpm {

// One set-up of all members (each from make_setup of its scene). They must share the grid,
// the particle count, the model, shape and precision, the stages and the time stepping; a
// difference is a SceneError naming the member and what differs.
SceneSetup make_ensemble_setup(const std::vector<SceneSetup>& members);

// Member k's particles [k n, (k + 1) n) of a frame of the ensemble (x, v, T and, where
// present, the diagnostics fields; not the subset).
Frame member_frame(const Frame& all, int k, long n);

struct EnsembleOptions {
  std::string out_dir;     // member_NNNN/ per member; empty: write nothing (tests)
  bool progress = true;
  bool frames = false;     // VTU frames per member at the scene's output times
  long max_span = 10000;
  const volatile std::sig_atomic_t* interrupt = nullptr;  // non-zero: stop, write what was sampled
  int first_member = 0;    // number of the first member in folder names (a group of a larger design)
};

struct MemberSummary {
  bool ok = true;
  std::string message;       // of a failed member: the bad particle (member-local index) and step
  long steps = 0;            // steps the member took (the failed one included)
  double t_end = 0;          // time of its last good state
  double wall_s = 0;         // ensemble wall time when the member finished or failed
  Measures final;
  double max_speed = 0;      // largest max_speed of the samples after the release (last stage)
  std::vector<double> runout_at;  // run-out at the scene's output times (NaN: not reached)
  std::vector<SeriesRow> series;
  std::vector<TrackRow> tracks;
  ConsolidationCheck consolidation;
  std::vector<std::pair<double, double>> profile;  // free surface of the last good sample
  std::vector<ForcePeak> forces;  // per boundary with force probes: peak force and impulse
};

struct EnsembleSummary {
  std::vector<MemberSummary> members;
  long steps = 0;
  double t_end = 0;
  double wall_s = 0;
  double files_s = 0;  // the members' files, written after the run (not in wall_s)
  std::string device;
  PhaseTimes times;
  UpdateStats stats;  // all members' updates (CUDA: with --update-stats on)
  int interrupted = 0;
};

// The time loop of run() for an ensemble: stages, shared step (fixed, or adaptive with the
// smallest stable step of the members), samples per member; a failing member is retired with
// its message and the others go on. `member_setups` are the set-ups make_ensemble_setup got.
EnsembleSummary run_ensemble(const SceneSetup& su, const std::vector<SceneSetup>& member_setups, Runner& runner,
                             const EnsembleOptions& opt);

}  // namespace granflow::mpm
