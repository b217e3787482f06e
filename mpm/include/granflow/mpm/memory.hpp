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
// One line: "memory: particles ... MiB, grid ... MiB, device total ... GiB (fp32 storage); host set-up ... GiB"
std::string memory_line(const SceneSetup& su);

}  // namespace granflow::mpm
