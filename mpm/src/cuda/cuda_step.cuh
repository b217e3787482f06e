// CUDA backend: one step, one kernel per phase, each calling the per-particle / per-node
// functions of kernels.hpp that the CPU twin also uses (docs/mpm.md, "GPU step").
// - P2G: per-particle atomics, or contributions of a warp's runs of particles sharing a stencil
//   summed by shuffles first (warp), or additionally summed in a shared-memory tile of the
//   block's stencil box and flushed once per node (tile; blocks whose box is too large fall
//   back to warp).
// - The grid kernel clears mass, momentum and force after using them, so no memset per step,
//   and returns at once on nodes no particle reached.
// - G2P: fused (kinematics and the whole constitutive update per thread), or split into a pass
//   of kinematics and elastic updates that lists the plastic points and a pass of their full
//   updates (CudaOptions::g2p_split; auto from two waves of the fused kernel up).
// enqueue_step chooses the kernels; config reports the same choice with each kernel's registers
// and occupancy.
#pragma once

#include <cuda_runtime.h>

#include <algorithm>
#include <climits>
#include <cstddef>
#include <cstdio>
#include <string>

#include <granflow/mpm/binning.hpp>

#include "cuda_runner_class.cuh"
#include "cuda_span.cuh"

namespace granflow::mpm {
namespace {

// ---- P2G ---------------------------------------------------------------------------------

enum P2GMode : int { kP2GAtomic = 0, kP2GWarp = 1, kP2GTile = 2 };  // CudaOptions::P2G

// Contributions of the particles of a warp: lanes with the same stencil (same key, adjacent
// after sorting) form a run; each run's contributions to each stencil node are summed by a
// segmented shuffle reduction and its first lane hands the sum to `sink`. Every lane of the
// warp must call this (invalid lanes: valid = false).
template <int D, class S, class Shape, class Sink>
__device__ __forceinline__ void scatter_warp(const P2GParticle<D, S>& q, const int* base, long key, bool valid,
                                             S inv_h, Sink&& sink) {
  constexpr int NC = 1 + 2 * D;
  const int lane = threadIdx.x & 31;
  const long prev = __shfl_up_sync(kFullMask, key, 1);
  const bool head = lane == 0 || prev != key;
  const unsigned heads = __ballot_sync(kFullMask, head);
  const int run_end = run_end_lane(heads, lane);  // first lane after my run
  int max_len = run_end - lane;
  for (int o = 16; o > 0; o >>= 1) max_len = max(max_len, __shfl_xor_sync(kFullMask, max_len, o));
  for (int k = 0; k < stencil_size<D, Shape::K>(); ++k) {
    int I[D];
    stencil_node<D, Shape::K>(base, k, I);
    S c[NC];
    if (valid) {
      p2g_contribution<D, S, Shape>(q, I, inv_h, c);
    } else {
      for (int f = 0; f < NC; ++f) c[f] = S(0);
    }
    for (int o = 1; o < max_len; o <<= 1)
      for (int f = 0; f < NC; ++f) {
        const S other = __shfl_down_sync(kFullMask, c[f], o);
        if (lane + o < run_end) c[f] += other;
      }
    if (head && valid) sink(I, c);
  }
}

// Contribution order: c[0] mass, c[1..D] momentum, c[1+D..2D] force, which are the grid
// fields 0..2D of GridLayout.
// kMembers: the particle's member k (and material) gives its values (apply_member) and k its block of nodes:
// node (and run key, and bin) k G + local node, so runs never join points of two members.
// A retired member's points contribute nothing. The tile mode is not built for ensembles (a
// block's box would have to stay inside one member's nodes): they scatter with warp sums.
template <int D, class S, class Model, class Shape, int kMode, bool kMembers>
__global__ void __launch_bounds__(kP2GBlock, p2g_min_blocks<S>())
    p2g_kernel(ParticleView<S> pv, GridView<S> gv, StepParams<D, S, Model> sp, const SpanControl* ctl,
               long* bin_keys) {
  static_assert(GridLayout<D>::M == 0 && GridLayout<D>::P == 1 && GridLayout<D>::F == 1 + D, "field order");
  static_assert(!(kMembers && kMode == kP2GTile), "ensembles scatter with warp sums (no tile)");
  constexpr int NC = 1 + 2 * D;
  constexpr int K = Shape::K;
  if (!ctl->active) return;
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  bool valid = p < pv.n;
  long node0 = 0;  // first node of the particle's member (kMembers)
  int k = 0;
  if constexpr (kMembers) {
    if (valid) {
      k = sp.members.of_particle(p);
      valid = !sp.members.skipped(k);
      node0 = static_cast<long>(k) * sp.members.nodes;
    }
  }
  auto node = [&](const int* I) -> long {
    if constexpr (kMembers) return node0 + sp.grid.linear(I); else return sp.grid.linear(I);
  };
  P2GParticle<D, S> q{};
  int base[D] = {};
  if (valid) {
    if constexpr (kMembers) {
      StepParams<D, S, Model> spm = sp;
      apply_member(spm, sp.members.value_index(k, p));
      q = p2g_load<D, S, Model>(pv, p, spm);
    } else {
      q = p2g_load<D, S, Model>(pv, p, sp);
    }
    stencil_base<D, S, Shape>(q.xi, sp.grid, base);  // G2P of the last step checked it is on the grid
    if (bin_keys) bin_keys[p] = node(base);  // bin of the particle (volumetric averaging)
  }
  auto to_global = [&](const int* I, const S* c) {
    const long n = node(I);
    for (int f = 0; f < NC; ++f) atomicAdd(&gv.f(f, n), c[f]);
  };
  if constexpr (kMode == kP2GAtomic) {
    if (!valid) return;
    for (int k = 0; k < stencil_size<D, K>(); ++k) {
      int I[D];
      stencil_node<D, K>(base, k, I);
      S c[NC];
      p2g_contribution<D, S, Shape>(q, I, sp.grid.inv_h, c);
      to_global(I, c);
    }
  } else {
    const long key = valid ? node(base) : -1 - static_cast<long>(threadIdx.x);
    if constexpr (kMode == kP2GWarp) {
      scatter_warp<D, S, Shape>(q, base, key, valid, sp.grid.inv_h, to_global);
    } else {
      constexpr int TN = tile_nodes<D>();
      __shared__ int s_lo[D], s_hi[D];
      __shared__ S s_tile[NC * TN];
      if (threadIdx.x < D) {
        s_lo[threadIdx.x] = INT_MAX;
        s_hi[threadIdx.x] = INT_MIN;
      }
      __syncthreads();
      if (valid)
        for (int d = 0; d < D; ++d) {
          atomicMin(&s_lo[d], base[d]);
          atomicMax(&s_hi[d], base[d]);
        }
      __syncthreads();
      TileBox<D, K> box;
      box.set(s_lo, s_hi);
      const long nt = box.size(TN);
      if (nt < 0) {  // the block's particles are spread out (unsorted, or a strip's end): no tile
        scatter_warp<D, S, Shape>(q, base, key, valid, sp.grid.inv_h, to_global);
        return;
      }
      for (int j = threadIdx.x; j < nt; j += blockDim.x)
        for (int f = 0; f < NC; ++f) s_tile[f * TN + j] = S(0);
      __syncthreads();
      scatter_warp<D, S, Shape>(q, base, key, valid, sp.grid.inv_h, [&](const int* I, const S* c) {
        const int j = box.local(I);
        for (int f = 0; f < NC; ++f) atomicAdd(&s_tile[f * TN + j], c[f]);
      });
      __syncthreads();
      for (int j = threadIdx.x; j < nt; j += blockDim.x) {
        int I[D];
        box.node(j, I);
        const long n = sp.grid.linear(I);
        for (int f = 0; f < NC; ++f) {
          const S v = s_tile[f * TN + j];
          if (v != S(0)) atomicAdd(&gv.f(f, n), v);
        }
      }
    }
  }
}

// ---- grid update -------------------------------------------------------------------------

// A node with zero mass received only zero-weight contributions (N = 0 implies grad N = 0 for
// both shapes), so its momentum and force are zero too and G2P weighs its velocities by zero:
// nothing to do. Other nodes are updated and their mass, momentum and force cleared for the
// next P2G (the grid starts zeroed).
// kMembers: over the nodes of all members; node I is node I - k G of member k's view (its
// values, masks and contact table).
// kKeepMass (linear hats): the node's mass is copied to gv.g2p_mass for G2P's light-node limit.
template <int D, class S, class Model, bool kBoundary, bool kContacts, bool kMembers, bool kKeepMass = false>
__global__ void grid_kernel(GridView<S> gv, StepParams<D, S, Model> sp0, const SpanControl* ctl) {
  if (!ctl->active) return;
  const long I = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (I >= gv.n) return;
  if (gv.f(GridLayout<D>::M, I) == S(0)) return;
  const StepParams<D, S, Model> sp = with_span(sp0, ctl);
  if constexpr (kMembers) {
    const int k = sp.members.of_node(I);
    StepParams<D, S, Model> spm = sp;
    apply_member(spm, sp.members.node_values(k));
    grid_update_node<D, S, Model, kBoundary, kContacts>(member_grid(gv, sp.members, k),
                                                        I - static_cast<long>(k) * sp.members.nodes, spm);
  } else {
    grid_update_node<D, S, Model, kBoundary, kContacts>(gv, I, sp);
  }
  if constexpr (kKeepMass) gv.g2p_mass[I] = gv.f(GridLayout<D>::M, I);
  for (int f = 0; f < 1 + 2 * D; ++f) gv.f(f, I) = S(0);
}

// Friction with the terrain on its listed nodes after the grid update (boundary.hpp
// terrain_contact); launched only for scenes with frictional terrain.
template <int D, class S>
__global__ void terrain_kernel(GridView<S> gv, const TerrainNode* nodes, long n, double mu, const SpanControl* ctl) {
  if (!ctl->active) return;
  const long i = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (i < n) terrain_contact<D, S>(gv, nodes[i], mu);
}

// ---- obstacles and the forces on the boundaries (launched only for scenes with them) ------

template <int D, class S>
__global__ void obstacle_kernel(GridView<S> gv, const ObstacleNode* nodes, long n, const SpanControl* ctl) {
  if (!ctl->active) return;
  const long i = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (i < n) obstacle_contact<D, S>(gv, nodes[i]);
}

// A probe's node mass and velocity before the holds (ProbeTrial), taken before the grid kernel
// clears mass, momentum and force (the CPU twin takes them after the holds: the same arithmetic).
template <int D, class S, class Model, bool kMembers>
__global__ void probe_trial_kernel(GridView<S> gv, StepParams<D, S, Model> sp0, const SpanControl* ctl,
                                   const ForceProbe* probes, long n, ProbeTrial* out) {
  if (!ctl->active) return;
  const long i = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (i >= n) return;
  StepParams<D, S, Model> sp = with_span(sp0, ctl);
  const long I = probes[i].node;
  if constexpr (kMembers) apply_member(sp, sp.members.node_values(sp.members.of_node(I)));
  out[i].m = trial_velocity<D, S, Model>(gv, I, sp, out[i].v, out[i].vd);
}

constexpr int kForceBlock = 128;

// One block per part: the step's sums of its probes (a fixed-order tree over the block), added
// to the part's sums since the last take; each probe's dp to its own sum.
template <int D, class S>
__global__ void force_parts_kernel(GridView<S> gv, const SpanControl* ctl, const ForceProbe* probes,
                                   const ProbeTrial* trial, const PartRange* parts, long np, ForceSums* step,
                                   ForceSums* acc, double* node_impulse) {
  if (!ctl->active) return;
  const PartRange pr = parts[blockIdx.x];
  ForceSums s;
  for (long i = pr.first + threadIdx.x; i < pr.first + pr.count; i += blockDim.x) {
    double dp[3] = {0, 0, 0};
    removed_momentum<D, S>(gv, probes[i].node, trial[i].m, trial[i].v, trial[i].vd, dp);
    add_probe_momentum<D>(s, probes[i], dp, pr.about);
    for (int d = 0; d < D; ++d) node_impulse[d * np + i] += dp[d];
  }
  __shared__ double red[8][kForceBlock];
  const double mine[8] = {s.impulse[0], s.impulse[1], s.impulse[2], s.normal,
                          s.tangential, s.moment[0], s.moment[1], s.moment[2]};
  for (int k = 0; k < 8; ++k) red[k][threadIdx.x] = mine[k];
  __syncthreads();
  for (int w = kForceBlock / 2; w > 0; w /= 2) {
    if (threadIdx.x < w)
      for (int k = 0; k < 8; ++k) red[k][threadIdx.x] += red[k][threadIdx.x + w];
    __syncthreads();
  }
  if (threadIdx.x != 0) return;
  ForceSums t;
  for (int d = 0; d < 3; ++d) {
    t.impulse[d] = red[d][0];
    t.moment[d] = red[5 + d][0];
  }
  t.normal = red[3][0];
  t.tangential = red[4][0];
  step[blockIdx.x] = t;
  add_force_step(acc[blockIdx.x], t, ctl->h);
}

// Each boundary's step: its parts' step sums in part order (a template: defined in every kernel file).
template <int D>
__global__ void force_boundaries_kernel(const SpanControl* ctl, const PartRange* parts, int n_parts,
                                        const ForceSums* step, ForceSums* acc, int nb) {
  if (!ctl->active) return;
  const int b = blockIdx.x * blockDim.x + threadIdx.x;
  if (b >= nb) return;
  ForceSums sb;
  for (int q = 0; q < n_parts; ++q)
    if (parts[q].boundary == b) add_step_sums(sb, step[q]);
  add_force_step(acc[b], sb, ctl->h);
}

// ---- G2P ---------------------------------------------------------------------------------
// kMembers: each particle with its member's values and view of the grid; a retired member's
// points are skipped (no update, no stable-step limit); a failure is recorded for the span and
// for the member (report_bad). The stable step is the smallest of all members: they share it.

template <int D, class S, class Model, class Shape, int kMaxThreads, int kMinBlocks, bool kMembers>
__global__ void __launch_bounds__(kMaxThreads, kMinBlocks)
    g2p_kernel(ParticleView<S> pv, GridView<S> gv, StepParams<D, S, Model> sp0, SpanControl* ctl,
               const std::uint32_t* ids, std::uint32_t* upd_info) {
  if (!ctl->active) return;
  const StepParams<D, S, Model> sp = with_span(sp0, ctl);
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  S lim = S(1e300);
  if constexpr (kMembers) {
    const int k = p < pv.n ? sp.members.of_particle(p) : 0;
    if (p < pv.n && !sp.members.skipped(k)) {
      StepParams<D, S, Model> spm = sp;
      apply_member(spm, sp.members.value_index(k, p));
      const std::uint32_t st =
          g2p_particle<D, S, Model, Shape>(pv, member_grid(gv, sp.members, k), p, spm, &lim, &upd_info[p]);
      if (st) report_bad<kMembers>(ctl, k, ids[p], st);
    }
  } else {
    if (p < pv.n) {
      const std::uint32_t st = g2p_particle<D, S, Model, Shape>(pv, gv, p, sp, &lim, &upd_info[p]);
      if (st) atomicMin(&ctl->bad, pack_bad(ids[p], st));
    }
  }
  finish_step(ctl, double(lim), sp.want_dt_limit);
}

// G2P split in two passes (CudaOptions::g2p_split). The first does the kinematics and the
// elastic part of every update (UpdatePart::ElasticOnly: half the registers of the full update)
// and lists the points whose step is plastic; the second runs the full update of the listed
// points only, packed into warps, so that elastic points wait for no return map and a warp's
// returns are of points that all need one. Each point gets the fused kernel's update (test
// PhaseTransition.ElasticOnlyUpdateIsTheFullUpdateOrDefersPlasticSteps).
template <int D, class S, class Model, class Shape, int kMinBlocks, bool kMembers>
__global__ void __launch_bounds__(kSplitBlock, kMinBlocks)
    g2p_elastic_kernel(ParticleView<S> pv, GridView<S> gv, StepParams<D, S, Model> sp0, SpanControl* ctl,
                       const std::uint32_t* ids, std::uint32_t* upd_info, std::uint32_t* deferred,
                       unsigned* n_deferred) {
  if (!ctl->active) return;
  const StepParams<D, S, Model> sp = with_span(sp0, ctl);
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  S lim = S(1e300);
  bool defer = false;
  if constexpr (kMembers) {
    const int k = p < pv.n ? sp.members.of_particle(p) : 0;
    if (p < pv.n && !sp.members.skipped(k)) {
      StepParams<D, S, Model> spm = sp;
      apply_member(spm, sp.members.value_index(k, p));
      const std::uint32_t st = g2p_particle<D, S, Model, Shape, UpdatePart::ElasticOnly>(
          pv, member_grid(gv, sp.members, k), p, spm, &lim, &upd_info[p]);
      defer = st == kDeferredPoint;
      if (st && !defer) report_bad<kMembers>(ctl, k, ids[p], st);
    }
  } else {
    if (p < pv.n) {
      const std::uint32_t st =
          g2p_particle<D, S, Model, Shape, UpdatePart::ElasticOnly>(pv, gv, p, sp, &lim, &upd_info[p]);
      defer = st == kDeferredPoint;
      if (st && !defer) atomicMin(&ctl->bad, pack_bad(ids[p], st));
    }
  }
  // one atomic per warp for its deferred points
  const unsigned mask = __ballot_sync(kFullMask, defer);
  if (mask) {
    const int lane = threadIdx.x & 31;
    const int leader = __ffs(mask) - 1;
    unsigned base = 0;
    if (lane == leader) base = atomicAdd(n_deferred, static_cast<unsigned>(__popc(mask)));
    base = __shfl_sync(kFullMask, base, leader);
    if (defer) deferred[base + __popc(mask & ((1u << lane) - 1u))] = static_cast<std::uint32_t>(p);
  }
  if (sp.want_dt_limit) reduce_dt_limit(ctl, double(lim));
}

// kMembers: the deferred points are of members that are not retired (the first pass skipped
// the others).
template <int D, class S, class Model, int kMaxThreads, int kMinBlocks, bool kMembers>
__global__ void __launch_bounds__(kMaxThreads, kMinBlocks)
    g2p_plastic_kernel(ParticleView<S> pv, StepParams<D, S, Model> sp0, SpanControl* ctl, const std::uint32_t* ids,
                       std::uint32_t* upd_info, const std::uint32_t* deferred, unsigned* n_deferred) {
  if (!ctl->active) return;
  const StepParams<D, S, Model> sp = with_span(sp0, ctl);
  const long i = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  S lim = S(1e300);
  if (i < static_cast<long>(*n_deferred)) {
    const long p = deferred[i];
    if constexpr (kMembers) {
      const int k = sp.members.of_particle(p);
      StepParams<D, S, Model> spm = sp;
      apply_member(spm, sp.members.value_index(k, p));
      const std::uint32_t st = constitutive_particle<D, S, Model>(pv, p, spm, S(NAN), &lim, &upd_info[p]);
      if (st) report_bad<kMembers>(ctl, k, ids[p], st);
    } else {
      const std::uint32_t st = constitutive_particle<D, S, Model>(pv, p, sp, S(NAN), &lim, &upd_info[p]);
      if (st) atomicMin(&ctl->bad, pack_bad(ids[p], st));
    }
  }
  finish_step(ctl, double(lim), sp.want_dt_limit, n_deferred);
}

// Split G2P for volumetric averaging: kinematics and bin sums, then the constitutive update.
// kMembers: bins are nodes of all members (P2G's keys k G + local); a retired member's points
// are skipped here and in constitutive_kernel.
template <int D, class S, class Model, class Shape, bool kMembers>
__global__ void g2p_kinematics_kernel(ParticleView<S> pv, GridView<S> gv, StepParams<D, S, Model> sp0,
                                      SpanControl* ctl, const std::uint32_t* ids, const long* keys, S* bin_v,
                                      S* bin_vtr, std::uint32_t* status) {
  if (!ctl->active) return;
  const StepParams<D, S, Model> sp = with_span(sp0, ctl);
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (p >= pv.n) return;
  if constexpr (kMembers) {
    const int k = sp.members.of_particle(p);
    if (sp.members.skipped(k)) return;
    StepParams<D, S, Model> spm = sp;
    apply_member(spm, sp.members.value_index(k, p));
    S lim = S(1e300);
    const std::uint32_t st = g2p_kinematics<D, S, Model, Shape>(pv, member_grid(gv, sp.members, k), p, spm, &lim);
    if (lim < S(1e300)) atomicMin(&ctl->lim, dt_limit_bits(double(lim)));  // light nodes (rare)
    status[p] = st;
    if (st) {
      report_bad<kMembers>(ctl, k, ids[p], st);
      return;
    }
    S V, tr;
    volumetric_rate<D, S, Model>(pv, p, spm, V, tr);
    atomicAdd(&bin_v[keys[p]], V);
    atomicAdd(&bin_vtr[keys[p]], V * tr);
  } else {
    S lim = S(1e300);
    const std::uint32_t st = g2p_kinematics<D, S, Model, Shape>(pv, gv, p, sp, &lim);
    if (lim < S(1e300)) atomicMin(&ctl->lim, dt_limit_bits(double(lim)));  // light nodes (rare)
    status[p] = st;
    if (st) {
      atomicMin(&ctl->bad, pack_bad(ids[p], st));
      return;
    }
    S V, tr;
    volumetric_rate<D, S, Model>(pv, p, sp, V, tr);
    atomicAdd(&bin_v[keys[p]], V);
    atomicAdd(&bin_vtr[keys[p]], V * tr);
  }
}

template <int D, class S, class Model, int kMaxThreads, int kMinBlocks, bool kMembers>
__global__ void __launch_bounds__(kMaxThreads, kMinBlocks)
    constitutive_kernel(ParticleView<S> pv, StepParams<D, S, Model> sp0, SpanControl* ctl, const std::uint32_t* ids,
                        const long* keys, const S* bin_v, const S* bin_vtr, std::uint32_t* status,
                        std::uint32_t* upd_info) {
  if (!ctl->active) return;
  const StepParams<D, S, Model> sp = with_span(sp0, ctl);
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  S lim = S(1e300);
  if constexpr (kMembers) {
    const int k = p < pv.n ? sp.members.of_particle(p) : 0;
    if (p < pv.n && !sp.members.skipped(k) && status[p] == 0) {  // else retired, or the kinematics failed
      StepParams<D, S, Model> spm = sp;
      apply_member(spm, sp.members.value_index(k, p));
      const long b = keys[p];
      const S tr_bar = bin_v[b] > S(0) ? bin_vtr[b] / bin_v[b] : S(0);
      const std::uint32_t st = constitutive_particle<D, S, Model>(pv, p, spm, tr_bar, &lim, &upd_info[p]);
      status[p] = st;
      if (st) report_bad<kMembers>(ctl, k, ids[p], st);
    }
  } else {
    if (p < pv.n && status[p] == 0) {  // else the kinematics already failed here
      const long b = keys[p];
      const S tr_bar = bin_v[b] > S(0) ? bin_vtr[b] / bin_v[b] : S(0);
      const std::uint32_t st = constitutive_particle<D, S, Model>(pv, p, sp, tr_bar, &lim, &upd_info[p]);
      status[p] = st;
      if (st) atomicMin(&ctl->bad, pack_bad(ids[p], st));
    }
  }
  finish_step(ctl, double(lim), sp.want_dt_limit);
}

// ---- the runner's step -------------------------------------------------------------------

// Split G2P: as asked, or (auto) from two waves of the fused kernel up, where the step is
// throughput-bound rather than bound by one point's latency.
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline bool CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::use_split() {
  if (opt_.g2p_split != CudaOptions::Split::Auto) return opt_.g2p_split == CudaOptions::Split::On;
  int dev = 0, sms = 0, per_sm = 0;
  check(cudaGetDevice(&dev), "cudaGetDevice");
  check(cudaDeviceGetAttribute(&sms, cudaDevAttrMultiProcessorCount, dev), "SM count");
  if (opt_.g2p_reg_cap)
    check(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, g2p_kernel<D, S, Model, Shape, 128, 3, kMembers>,
                                                        opt_.g2p_block, 0), "occupancy");
  else
    check(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, g2p_kernel<D, S, Model, Shape, 256, 1, kMembers>,
                                                        opt_.g2p_block, 0), "occupancy");
  fused_waves_ = double(n_) / (double(sms) * std::max(1, per_sm) * opt_.g2p_block);
  return fused_waves_ >= 2.0;
}

// Loads the step kernels now (lazy module loading would otherwise load them during the
// first graph capture, which older drivers refuse).
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::preload() const {
  cudaFuncAttributes a;
  if constexpr (!kMembers)  // ensembles: no tile mode (p2g_kernel)
    check(cudaFuncGetAttributes(&a, reinterpret_cast<const void*>(p2g_kernel<D, S, Model, Shape, kP2GTile, false>)),
          "load kernels");
  const void* k[] = {reinterpret_cast<const void*>(p2g_kernel<D, S, Model, Shape, kP2GAtomic, kMembers>),
                     reinterpret_cast<const void*>(p2g_kernel<D, S, Model, Shape, kP2GWarp, kMembers>),
                     reinterpret_cast<const void*>(grid_kernel<D, S, Model, kBoundary, false, kMembers, kKeepMass>),
                     reinterpret_cast<const void*>(grid_kernel<D, S, Model, kBoundary, kBoundary, kMembers, kKeepMass>),
                     reinterpret_cast<const void*>(g2p_kernel<D, S, Model, Shape, 256, 1, kMembers>),
                     reinterpret_cast<const void*>(g2p_kernel<D, S, Model, Shape, 128, 3, kMembers>),
                     reinterpret_cast<const void*>(g2p_kinematics_kernel<D, S, Model, Shape, kMembers>),
                     reinterpret_cast<const void*>(constitutive_kernel<D, S, Model, 256, 1, kMembers>),
                     reinterpret_cast<const void*>(constitutive_kernel<D, S, Model, 128, 3, kMembers>),
                     reinterpret_cast<const void*>(g2p_elastic_kernel<D, S, Model, Shape, kElastic, kMembers>),
                     reinterpret_cast<const void*>(g2p_elastic_kernel<D, S, Model, Shape, kElasticCap, kMembers>),
                     reinterpret_cast<const void*>(g2p_plastic_kernel<D, S, Model, kSplitBlock, kPlastic, kMembers>)};
  for (const void* f : k) check(cudaFuncGetAttributes(&a, f), "load kernels");
  if constexpr (kTerrain)
    if (n_terrain_ > 0) check(cudaFuncGetAttributes(&a, reinterpret_cast<const void*>(terrain_kernel<D, S>)), "load kernels");
  if constexpr (kBoundary) {
    if (n_obstacle_ > 0) check(cudaFuncGetAttributes(&a, reinterpret_cast<const void*>(obstacle_kernel<D, S>)), "load kernels");
    if (n_probes_ > 0) {
      const void* f[] = {reinterpret_cast<const void*>(probe_trial_kernel<D, S, Model, kMembers>),
                         reinterpret_cast<const void*>(force_parts_kernel<D, S>),
                         reinterpret_cast<const void*>(force_boundaries_kernel<D>)};
      for (const void* x : f) check(cudaFuncGetAttributes(&a, x), "load kernels");
    }
  }
}

// ---- update statistics (CudaOptions::update_stats) -------------------------------------------
// UpdateStats summed on the device: each block sums its points' records in shared memory (a warp
// is a group of 32 consecutive slots, as the CPU twin groups them), then adds its sums to the
// run's. The per-step largest count is not kept (steps = 0).
struct DeviceUpdateStats {
  unsigned long long updates, substeps, substep_limit, tension_cutoff, vs_clamped, separated;
  unsigned long long plastic, halvings, floored, bracketed, warp_max_substeps, warps, max_substeps;
  unsigned long long plastic_evaluations[kCostBins], group_max[kCostBins], slow_in_group[33];
};
inline constexpr int kStatsBlock = 256;

__global__ void __launch_bounds__(kStatsBlock) update_stats_kernel(const std::uint32_t* info, long n,
                                                                   const SpanControl* ctl, DeviceUpdateStats* out) {
  if (!ctl->active) return;
  using U = unsigned long long;
  constexpr int kWords = sizeof(DeviceUpdateStats) / sizeof(U);
  __shared__ DeviceUpdateStats s;
  U* sw = reinterpret_cast<U*>(&s);
  for (int i = threadIdx.x; i < kWords; i += blockDim.x) sw[i] = 0;
  __syncthreads();
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  const bool valid = p < n;
  const std::uint32_t f = valid ? info[p] : 0u;
  const int e = valid ? record::evaluations(f) : 0;
  if (valid) {
    atomicAdd(&s.updates, U(1));
    atomicAdd(&s.substeps, U(e));
    if (f & info::kSubstepLimit) atomicAdd(&s.substep_limit, U(1));
    if (f & info::kTensionCutoff) atomicAdd(&s.tension_cutoff, U(1));
    if (f & info::kVsClamped) atomicAdd(&s.vs_clamped, U(1));
    if (f & kSeparatedFlag) atomicAdd(&s.separated, U(1));
    if (f & record::kPlastic) {
      atomicAdd(&s.plastic, U(1));
      atomicAdd(&s.plastic_evaluations[e < kCostBins - 1 ? e : kCostBins - 1], U(1));
      atomicAdd(&s.halvings, U(record::halvings(f)));
      if (f & record::kFloored) atomicAdd(&s.floored, U(1));
      if (f & record::kBracketed) atomicAdd(&s.bracketed, U(1));
    }
  }
  int m = e;
  for (int off = 16; off > 0; off >>= 1) m = max(m, __shfl_xor_sync(0xffffffffu, m, off));
  const int slow = __popc(__ballot_sync(0xffffffffu, valid && e >= kSlowEvaluations));
  const bool any = __any_sync(0xffffffffu, valid);
  if ((threadIdx.x & 31) == 0 && any) {
    atomicAdd(&s.warp_max_substeps, U(m));
    atomicAdd(&s.warps, U(1));
    atomicMax(&s.max_substeps, U(m));
    atomicAdd(&s.group_max[m < kCostBins - 1 ? m : kCostBins - 1], U(1));
    atomicAdd(&s.slow_in_group[slow], U(1));
  }
  __syncthreads();
  U* ow = reinterpret_cast<U*>(out);
  constexpr int kMax = offsetof(DeviceUpdateStats, max_substeps) / sizeof(U);
  for (int i = threadIdx.x; i < kWords; i += blockDim.x)
    if (sw[i]) {
      if (i == kMax) atomicMax(&ow[i], sw[i]);
      else atomicAdd(&ow[i], sw[i]);
    }
}

template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline UpdateStats CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::update_stats() const {
  UpdateStats u;
  if (!stats_) return u;
  DeviceUpdateStats h;
  check(cudaStreamSynchronize(stream_), "update stats");
  check(cudaMemcpy(&h, stats_, sizeof h, cudaMemcpyDeviceToHost), "update stats");
  u.updates = long(h.updates);
  u.substeps = long(h.substeps);
  u.substep_limit = long(h.substep_limit);
  u.tension_cutoff = long(h.tension_cutoff);
  u.vs_clamped = long(h.vs_clamped);
  u.separated = long(h.separated);
  u.plastic = long(h.plastic);
  u.halvings = long(h.halvings);
  u.floored = long(h.floored);
  u.bracketed = long(h.bracketed);
  u.warp_max_substeps = long(h.warp_max_substeps);
  u.warps = long(h.warps);
  u.max_substeps = long(h.max_substeps);
  for (int i = 0; i < kCostBins; ++i) {
    u.plastic_evaluations[i] = long(h.plastic_evaluations[i]);
    u.group_max[i] = long(h.group_max[i]);
  }
  for (int i = 0; i < 33; ++i) u.slow_in_group[i] = long(h.slow_in_group[i]);
  return u;
}

// Queues one step (kernels only: capturable): P2G, grid update and G2P, which a scene split
// over GPUs (cuda_slabs.cuh) queues one by one with its exchanges in between.
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::enqueue_step(bool timed) {
  if (timed) cudaEventRecord(ev_[kP2G0], stream_);
  enqueue_p2g();
  if (timed) cudaEventRecord(ev_[kGrid0], stream_);
  enqueue_grid();
  if (timed) cudaEventRecord(ev_[kG2P0], stream_);
  enqueue_g2p();
  if (timed) cudaEventRecord(ev_[kG2P1], stream_);
}

template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::enqueue_p2g() {
  const ParticleView<S> pv = part_view();
  const GridView<S> gv{grid_, nn_, masks_[stage_]};
  const unsigned pb = blocks_for(n_, kP2GBlock);
  long* bk = sp_.vol_avg ? keys_ : nullptr;
  switch (opt_.p2g) {
    case CudaOptions::P2G::Atomic:
      p2g_kernel<D, S, Model, Shape, kP2GAtomic, kMembers><<<pb, kP2GBlock, 0, stream_>>>(pv, gv, sp_, ctl_, bk);
      break;
    case CudaOptions::P2G::Warp:
      p2g_kernel<D, S, Model, Shape, kP2GWarp, kMembers><<<pb, kP2GBlock, 0, stream_>>>(pv, gv, sp_, ctl_, bk);
      break;
    case CudaOptions::P2G::Tile:  // single runs only (the constructor sets warp for ensembles)
      if constexpr (!kMembers)
        p2g_kernel<D, S, Model, Shape, kP2GTile, false><<<pb, kP2GBlock, 0, stream_>>>(pv, gv, sp_, ctl_, bk);
      break;
  }
}

template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::enqueue_grid() {
  GridView<S> gv{grid_, nn_, masks_[stage_]};
  gv.g2p_mass = g2p_mass_;
  const unsigned gb = blocks_for(nn_, kGridBlock);
  if constexpr (kBoundary)
    if (n_probes_ > 0)
      probe_trial_kernel<D, S, Model, kMembers><<<blocks_for(n_probes_, kGridBlock), kGridBlock, 0, stream_>>>(
          gv, sp_, ctl_, probes_, n_probes_, trial_);
  if (kBoundary && contacts_[stage_])  // friction or a lifting gate (boundary.hpp)
    grid_kernel<D, S, Model, kBoundary, kBoundary, kMembers, kKeepMass><<<gb, kGridBlock, 0, stream_>>>(gv, sp_, ctl_);
  else
    grid_kernel<D, S, Model, kBoundary, false, kMembers, kKeepMass><<<gb, kGridBlock, 0, stream_>>>(gv, sp_, ctl_);
  if constexpr (kTerrain)
    if (n_terrain_ > 0)
      terrain_kernel<D, S><<<blocks_for(n_terrain_, kGridBlock), kGridBlock, 0, stream_>>>(gv, terrain_, n_terrain_,
                                                                                         terrain_mu_, ctl_);
  if constexpr (kBoundary) {
    if (n_obstacle_ > 0)
      obstacle_kernel<D, S><<<blocks_for(n_obstacle_, kGridBlock), kGridBlock, 0, stream_>>>(gv, obstacle_,
                                                                                            n_obstacle_, ctl_);
    if (n_probes_ > 0) {
      force_parts_kernel<D, S><<<n_parts_, kForceBlock, 0, stream_>>>(gv, ctl_, probes_, trial_, parts_, n_probes_,
                                                                      part_step_, force_acc_, node_impulse_);
      force_boundaries_kernel<D><<<blocks_for(n_boundaries_, 64), 64, 0, stream_>>>(ctl_, parts_, n_parts_, part_step_, force_acc_ + n_parts_,
                                                     n_boundaries_);
    }
  }
}

template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::enqueue_g2p() {
  const long nn = nn_;  // of all members
  const ParticleView<S> pv = part_view();
  GridView<S> gv{grid_, nn, masks_[stage_]};
  gv.g2p_mass = g2p_mass_;
  const unsigned pb = blocks_for(n_, kP2GBlock);
  const unsigned cb = blocks_for(n_, opt_.g2p_block);
  if (split()) {
    const unsigned eb = blocks_for(n_, kSplitBlock);
    if (opt_.g2p_reg_cap)
      g2p_elastic_kernel<D, S, Model, Shape, kElasticCap, kMembers>
          <<<eb, kSplitBlock, 0, stream_>>>(pv, gv, sp_, ctl_, ids_, info_, deferred_, n_deferred_);
    else
      g2p_elastic_kernel<D, S, Model, Shape, kElastic, kMembers>
          <<<eb, kSplitBlock, 0, stream_>>>(pv, gv, sp_, ctl_, ids_, info_, deferred_, n_deferred_);
    g2p_plastic_kernel<D, S, Model, kSplitBlock, kPlastic, kMembers><<<eb, kSplitBlock, 0, stream_>>>(
        pv, sp_, ctl_, ids_, info_, deferred_, n_deferred_);
  } else if (!sp_.vol_avg) {
    if (opt_.g2p_reg_cap)
      g2p_kernel<D, S, Model, Shape, 128, 3, kMembers>
          <<<cb, opt_.g2p_block, 0, stream_>>>(pv, gv, sp_, ctl_, ids_, info_);
    else
      g2p_kernel<D, S, Model, Shape, 256, 1, kMembers>
          <<<cb, opt_.g2p_block, 0, stream_>>>(pv, gv, sp_, ctl_, ids_, info_);
  } else {
    check(cudaMemsetAsync(bins_, 0, sizeof(S) * 2 * nn, stream_), "clear bins");
    g2p_kinematics_kernel<D, S, Model, Shape, kMembers>
        <<<pb, kP2GBlock, 0, stream_>>>(pv, gv, sp_, ctl_, ids_, keys_, bins_, bins_ + nn, status_);
    if (opt_.g2p_reg_cap)
      constitutive_kernel<D, S, Model, 128, 3, kMembers><<<cb, opt_.g2p_block, 0, stream_>>>(
          pv, sp_, ctl_, ids_, keys_, bins_, bins_ + nn, status_, info_);
    else
      constitutive_kernel<D, S, Model, 256, 1, kMembers><<<cb, opt_.g2p_block, 0, stream_>>>(
          pv, sp_, ctl_, ids_, keys_, bins_, bins_ + nn, status_, info_);
  }
  if (stats_) update_stats_kernel<<<blocks_for(n_, kStatsBlock), kStatsBlock, 0, stream_>>>(info_, n_, ctl_, stats_);
}

template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline std::string CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::config() const {
  std::string s = "CUDA options: " + describe(opt_) + "\n";
  if constexpr (kMembers) {
    char buf[200];
    std::snprintf(buf, sizeof buf, "  ensemble: %d members of %ld points and %ld grid nodes (P2G: no tile mode)\n",
                  sp_.members.count, sp_.members.particles, sp_.members.nodes);
    s += buf;
  }
  if (opt_.g2p_split == CudaOptions::Split::Auto && !sp_.vol_avg) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "  G2P: %s (the fused kernel would run %.2f waves; split from 2)\n",
                  split() ? "split" : "fused", fused_waves_);
    s += buf;
  }
  const char* p2g_name = opt_.p2g == CudaOptions::P2G::Atomic ? "P2G (atomic)"
                         : opt_.p2g == CudaOptions::P2G::Warp ? "P2G (warp)"
                                                              : "P2G (tile)";
  if (opt_.p2g == CudaOptions::P2G::Atomic)
    s += kernel_info(p2g_name, p2g_kernel<D, S, Model, Shape, kP2GAtomic, kMembers>, kP2GBlock);
  else if (opt_.p2g == CudaOptions::P2G::Warp)
    s += kernel_info(p2g_name, p2g_kernel<D, S, Model, Shape, kP2GWarp, kMembers>, kP2GBlock);
  else if constexpr (!kMembers)
    s += kernel_info(p2g_name, p2g_kernel<D, S, Model, Shape, kP2GTile, false>, kP2GBlock);
  s += kernel_info("grid update", grid_kernel<D, S, Model, kBoundary, false, kMembers, kKeepMass>, kGridBlock);
  if constexpr (kTerrain)
    if (n_terrain_ > 0) s += kernel_info("terrain friction", terrain_kernel<D, S>, kGridBlock);
  if (split()) {
    if (opt_.g2p_reg_cap)
      s += kernel_info("G2P + elastic part", g2p_elastic_kernel<D, S, Model, Shape, kElasticCap, kMembers>,
                       kSplitBlock);
    else
      s += kernel_info("G2P + elastic part", g2p_elastic_kernel<D, S, Model, Shape, kElastic, kMembers>, kSplitBlock);
    s += kernel_info("plastic return of the deferred points", g2p_plastic_kernel<D, S, Model, kSplitBlock, kPlastic, kMembers>,
                     kSplitBlock);
  } else if (!sp_.vol_avg) {
    if (opt_.g2p_reg_cap)
      s += kernel_info("G2P + constitutive", g2p_kernel<D, S, Model, Shape, 128, 3, kMembers>, opt_.g2p_block);
    else
      s += kernel_info("G2P + constitutive", g2p_kernel<D, S, Model, Shape, 256, 1, kMembers>, opt_.g2p_block);
  } else {
    s += kernel_info("G2P kinematics", g2p_kinematics_kernel<D, S, Model, Shape, kMembers>, kP2GBlock);
    if (opt_.g2p_reg_cap)
      s += kernel_info("constitutive", constitutive_kernel<D, S, Model, 128, 3, kMembers>, opt_.g2p_block);
    else
      s += kernel_info("constitutive", constitutive_kernel<D, S, Model, 256, 1, kMembers>, opt_.g2p_block);
  }
  return s;
}

}  // namespace
}  // namespace granflow::mpm
