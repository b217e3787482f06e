// Checkpoints of MPM runs: the particle state and everything the driver's time loop carries
// from one step to the next, in one binary file (format: docs/reliability.md).
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "forces.hpp"
#include "maps.hpp"
#include "measures.hpp"
#include "runner.hpp"

namespace granflow::mpm {

// Not a checkpoint, another version, truncated, corrupt, or written for another scene.
class CheckpointError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The time loop between two steps (mpm::run).
struct LoopState {
  double t = 0;
  long step = 0;
  double dt = 0;            // next step (adaptive: the last stable limit)
  int stage = 0;
  double t_stage_end = 0;   // end of `stage`
  double next_sample = 0;
  long next_out = 0;        // index into the sorted output.times
  int frame_no = 0;
  std::vector<std::pair<double, std::string>> pvd;
  std::vector<SeriesRow> series;
  std::vector<TrackRow> tracks;
  std::vector<GaugeRow> gauges;
  std::vector<Measures> material_series;  // RunSummary::material_series
  Frame last_good;          // light frame of the last sample (x, v, T)
  double last_good_t = 0;
  ConsolidationCheck consolidation;
  UpdateStats stats;        // summed over the steps before the checkpoint
  double wall_s = 0;
  MapsState maps;           // 3D terrain runs: the maps' maxima and deposit rows so far
  ForcesState forces;       // boundary forces: rows so far, the runner's sums since the last sample
};

struct Checkpoint {
  std::uint64_t scene_hash = 0;  // RunOptions::scene_hash of the run that wrote it
  HostParticles particles;
  LoopState loop;
};

// File name inside the output directory.
inline constexpr const char* kCheckpointFile = "checkpoint.bin";

std::string encode_checkpoint(const Checkpoint& c);
Checkpoint decode_checkpoint(std::string_view bytes);
// Through io::write_file, synced: a kill or a full disk never leaves a partial checkpoint, and
// a failed write (io::OutputError) leaves the previous one.
void write_checkpoint(const std::string& path, const Checkpoint& c);
Checkpoint read_checkpoint(const std::string& path);
// The files of the output folder when `c` was written: the checkpoint, the frame index, the
// series and the frames it lists. --restart removes every other (written after it).
std::vector<std::string> checkpoint_outputs(const Checkpoint& c);
// Refuses a checkpoint of another scene (hash) or of a set-up it does not fit.
void check_checkpoint(const Checkpoint& c, const SceneSetup& su, std::uint64_t scene_hash);

// 64-bit FNV-1a, continued from h.
std::uint64_t fnv1a(std::string_view bytes, std::uint64_t h = 14695981039346656037ull);

}  // namespace granflow::mpm
