// Memory a scene needs: the device buffers of a runner (particle and grid storage in the
// scene's precision, per-particle work arrays, per-stage node masks) and the host set-up.
#pragma once

#include <string>

#include "runner.hpp"

namespace granflow::mpm {

struct MemoryEstimate {
  double particle_bytes = 0;  // particle fields + per-particle work arrays (step limit, status, record, bin key)
  double grid_bytes = 0;      // grid fields + per-node bin sums + node masks of every stage
  double host_bytes = 0;      // HostParticles (double) of the set-up
  int scalar_bytes = 8;       // 4 in the fp32 and mixed precisions
  double device_bytes() const { return particle_bytes + grid_bytes; }
};

// Estimate for the CUDA runner's buffers (the CPU twin's are within a few percent).
MemoryEstimate estimate_memory(const SceneSetup& su);
// What each member of an ensemble like `member` (one member's set-up) takes, for granflow
// ensemble's check before anything is allocated. Runner: its buffers (estimate_memory of the
// member) and the snapshot of a sample; on the GPU for CUDA, in host memory for the CPU twin.
// Host, either backend: the member's set-up twice (its own and its share of the combined one;
// the particle arrays as allocated, the masks, the scene), the sample frames and the frame at
// a stage's end, and the summary (a row per sample, per tracked point, and the free surface).
struct EnsembleMemory {
  double runner_per_member = 0, host_per_member = 0;
};
EnsembleMemory estimate_ensemble_memory(const SceneSetup& member);

// One line: "memory: particles ... MiB, grid ... MiB, device total ... GiB (fp32 storage); host set-up ... GiB"
std::string memory_line(const SceneSetup& su);

}  // namespace granflow::mpm
