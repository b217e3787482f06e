#include <granflow/mpm/layout.hpp>
#include <granflow/mpm/memory.hpp>

#include <cstdint>
#include <cstdio>

namespace granflow::mpm {

namespace {

template <int D>
int particle_fields(bool coll) {
  return coll ? ParticleLayout<D, true>::N : ParticleLayout<D, false>::N;
}

}  // namespace

MemoryEstimate estimate_memory(const SceneSetup& su) {
  const Scene& sc = su.scene;
  MemoryEstimate m;
  m.scalar_bytes = sc.precision == Precision::FP64 ? 8 : 4;
  const bool coll = sc.material.model == ModelKind::PhaseTransition;
  const int nf = sc.dim == 3 ? particle_fields<3>(coll) : particle_fields<2>(coll);
  const int gf = sc.dim == 3 ? GridLayout<3>::N : GridLayout<2>::N;
  const double n = double(su.particles.n), nodes = double(su.n_nodes) * su.members;  // all members
  const double S = m.scalar_bytes;
  // fields, step limit (S), status and update record (uint32 each), bin key (long)
  m.particle_bytes = n * (nf * S + S + 2 * sizeof(std::uint32_t) + sizeof(long));
  // fields, two bin sums (volumetric averaging), one mask byte per node and stage
  m.grid_bytes = nodes * (gf * S + 2 * S);
  for (const auto& block : su.stage_masks) m.grid_bytes += double(block.size());
  const double host_fields = 3.0 * sc.dim + 1 + 6 + 6 + sc.dim * sc.dim + 3;  // x, v, m, sig, sigf, L, eps, e, s
  m.host_bytes = n * host_fields * sizeof(double);
  return m;
}

std::string memory_line(const SceneSetup& su) {
  const MemoryEstimate m = estimate_memory(su);
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "memory: particles %.1f MiB, grid %.1f MiB, device total %.2f GiB (%s, %d-byte storage); host "
                "set-up %.2f GiB",
                m.particle_bytes / 1048576.0, m.grid_bytes / 1048576.0, m.device_bytes() / 1073741824.0,
                precision_name(su.scene.precision), m.scalar_bytes, m.host_bytes / 1073741824.0);
  return buf;
}

}  // namespace granflow::mpm
