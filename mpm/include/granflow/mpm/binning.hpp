// Particle order for the GPU (docs/mpm_gpu.md, "Particles sorted by cell"): particles are sorted
// by a key of the lowest node of their stencil so that neighbours in memory are neighbours in
// space; P2G then sums a block's contributions in a shared-memory tile (TileBox) and flushes
// each touched node once. Written as GF_HD functions so the CPU tests check the same arithmetic.
//
// Bookkeeping of a reordered particle buffer: slot i holds the particle of original index
// ids[i] (the set-up's order); a sort with permutation perm moves slot perm[i] to slot i
// (gather), ids along with it; inv[ids[i]] = i finds the slot of an original index. Whatever
// leaves the backend (frames, downloads, bad particles) is put back in the original order.
#pragma once

#include <cstdint>

#include "kernels.hpp"
#include "layout.hpp"

namespace granflow::mpm {

// Keys walk along x through strips kSortStrip nodes thick in the other axes: 128 consecutive
// particles (4 per cell in 2D) cover about 8 x 4 cells, a stencil box of about 10 x 6 nodes.
inline constexpr int kSortStrip = 4;

// Sort key of a stencil base node (clamped onto the grid): strip of axes D-1..1 (slowest),
// then x, then the offsets inside the strip. Keys are below sort_key_bound.
template <int D>
GF_HDI std::uint64_t sort_key(const int* base_in, const int* nodes) {
  int base[D];
  for (int d = 0; d < D; ++d) base[d] = base_in[d] < 0 ? 0 : (base_in[d] >= nodes[d] ? nodes[d] - 1 : base_in[d]);
  std::uint64_t k = 0;
  for (int d = D - 1; d >= 1; --d)
    k = k * static_cast<std::uint64_t>((nodes[d] + kSortStrip - 1) / kSortStrip) + static_cast<std::uint64_t>(base[d] / kSortStrip);
  k = k * static_cast<std::uint64_t>(nodes[0]) + static_cast<std::uint64_t>(base[0]);
  for (int d = D - 1; d >= 1; --d) k = k * kSortStrip + static_cast<std::uint64_t>(base[d] % kSortStrip);
  return k;
}

template <int D>
GF_HDI std::uint64_t sort_key_bound(const int* nodes) {
  std::uint64_t b = static_cast<std::uint64_t>(nodes[0]);
  for (int d = 1; d < D; ++d) b *= static_cast<std::uint64_t>((nodes[d] + kSortStrip - 1) / kSortStrip) * kSortStrip;
  return b;
}

// Stencil base of a particle from its stored position (P2G, sort keys).
template <int D, class S, class Shape, bool kColl>
GF_HDI void particle_base(const ParticleView<S>& pv, long p, const GridDesc<D, S>& g, S* xi, int* base) {
  using Lay = ParticleLayout<D, kColl>;
  for (int d = 0; d < D; ++d) xi[d] = (pv.f(Lay::X + d, p) - g.origin[d]) * g.inv_h;
  stencil_base<D, S, Shape>(xi, g, base);
}

// Moves particle `from` of src into slot i of dst (all nfields fields).
template <class S>
GF_HDI void gather_slot(const ParticleView<S>& src, const ParticleView<S>& dst, int nfields, long i, long from) {
  for (int f = 0; f < nfields; ++f) dst.f(f, i) = src.f(f, from);
}

// Runs of a warp in P2G: lanes whose particles share a stencil (equal keys, adjacent after
// sorting) sum their contributions before one of them scatters. heads: bit l set where lane l
// starts a run (lane 0 always). Returns the first lane after the run containing `lane`.
GF_HDI int run_end_lane(std::uint32_t heads, int lane) {
  const std::uint32_t above = lane >= 31 ? 0u : heads & (~0u << (lane + 1));
#ifdef __CUDA_ARCH__
  return above ? __ffs(above) - 1 : 32;
#else
  return above ? __builtin_ffs(static_cast<int>(above)) - 1 : 32;
#endif
}

// Box of grid nodes covered by the stencils of a group of particles: lo .. lo + ext - 1 per
// axis, built from the smallest and largest stencil base of the group. Local index x-fastest.
template <int D, int K>
struct TileBox {
  int lo[D];
  int ext[D];
  GF_HDI void set(const int* base_min, const int* base_max) {
    for (int d = 0; d < D; ++d) {
      lo[d] = base_min[d];
      ext[d] = base_max[d] - base_min[d] + K;
    }
  }
  // Number of nodes, or -1 beyond `cap` (also for an empty group: base_max < base_min).
  GF_HDI long size(long cap) const {
    long n = 1;
    for (int d = 0; d < D; ++d) {
      if (ext[d] < K || ext[d] > cap) return -1;
      n *= ext[d];
      if (n > cap) return -1;
    }
    return n;
  }
  GF_HDI int local(const int* I) const {
    int j = I[D - 1] - lo[D - 1];
    for (int d = D - 2; d >= 0; --d) j = j * ext[d] + (I[d] - lo[d]);
    return j;
  }
  GF_HDI void node(int j, int* I) const {
    for (int d = 0; d < D; ++d) {
      I[d] = lo[d] + j % ext[d];
      j /= ext[d];
    }
  }
};

}  // namespace granflow::mpm
