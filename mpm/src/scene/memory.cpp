#include <granflow/mpm/layout.hpp>
#include <granflow/mpm/driver.hpp>
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
  m.grid_bytes += double(su.terrain.size()) * sizeof(TerrainNode);  // frictional terrain's nodes
  const double host_fields = 3.0 * sc.dim + 1 + 6 + 6 + sc.dim * sc.dim + 3;  // x, v, m, sig, sigf, L, eps, e, s
  m.host_bytes = n * host_fields * sizeof(double);
  return m;
}

namespace {

template <class T>
double bytes_of(const std::vector<T>& v) {
  return double(v.capacity()) * sizeof(T);
}

// One member's set-up as held: the particle arrays, masks, tracked indices and the scene.
double setup_bytes(const SceneSetup& su) {
  const HostParticles& p = su.particles;
  double b = sizeof(SceneSetup);
  for (const auto* v : {&p.x, &p.v, &p.m, &p.sig, &p.sigf, &p.L, &p.eps, &p.e, &p.s}) b += bytes_of(*v);
  for (const auto& m : su.stage_masks) b += bytes_of(m) + sizeof(m);
  b += bytes_of(su.tracked) + bytes_of(su.origin) + bytes_of(su.nodes);
  const Scene& sc = su.scene;
  for (const auto& [key, line] : sc.lines) b += 64 + key.capacity() + sizeof(line);  // map node
  b += double(sc.stages.size()) * sizeof(Stage) + double(sc.tracks.size()) * sizeof(Track) +
       double(sc.walls.size()) * sizeof(Wall) + double(sc.bodies.size()) * sizeof(Body);
  for (const Body& body : sc.bodies) b += bytes_of(body.poly_x) + bytes_of(body.poly_y);
  return b;
}

}  // namespace

EnsembleMemory estimate_ensemble_memory(const SceneSetup& su) {
  const Scene& sc = su.scene;
  const MemoryEstimate m = estimate_memory(su);
  const double n = double(su.particles.n), D = sc.dim;
  EnsembleMemory e;
  // the runner, and the snapshot of a sample (x, v and T: Runner::snapshot)
  e.runner_per_member = m.device_bytes() + n * (2 * D + 1) * m.scalar_bytes;
  // samples: every series_dt, at the output times and at each stage's end
  double samples = 2 + double(sc.output.times.size()) + double(sc.stages.size());
  if (sc.output.series_dt > 0) samples += sc.duration() / sc.output.series_dt;
  const double rows = samples * (sizeof(SeriesRow) + double(sc.tracks.size()) * sizeof(TrackRow));
  const double surface = 2 * 16 * (sc.size.empty() ? 0.0 : sc.size[0] / sc.h + 2);  // free surface and a copy
  const double frames = n * 8 * (2 * (2 * D + 1) + (2 * D + 10));  // two light frames, one with diagnostics
  // 2 rows: a vector's growth; 1.15: the allocator's own (block headers, pages kept after a free)
  e.host_per_member = 1.15 * (2 * setup_bytes(su) + frames + 2 * rows + surface);
  return e;
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
