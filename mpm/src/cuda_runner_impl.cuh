// CUDA backend: one kernel per phase, each calling the per-particle / per-node functions of
// kernels.hpp that the CPU twin also uses (docs/mpm.md, "GPU step"). Included by the
// cuda_kernels_*.cu files (one per model and shape), which instantiate make_cuda_runner_t;
// cuda_runner.cu dispatches to them.
//
// - Spans: a span of steps is queued with no host round-trip. Step size, time, failure flag
//   and step count live on the device (SpanControl); every kernel reads `active` at its start
//   and returns at once after the span ended or failed; the last block of each step's final
//   kernel records the step and plans the next one (adaptive dt from a device min-reduction,
//   landing on t_land by span.hpp's rule). One synchronisation at the end of a span.
// - CUDA graphs: chunks of 1, 2, 4, ... graph_steps steps are captured once per stage and
//   replayed; dt, flip and damping are read from SpanControl, so they need no re-capture.
// - Sorting: every sort_every steps particles are reordered by the cell key of binning.hpp
//   (cub radix sort, gather into a second buffer, copied back so kernel arguments and graphs
//   stay valid); ids_ keeps each slot's original index and everything leaving the backend is
//   put back into the original order.
// - P2G: per-particle atomics, or contributions of a warp's runs of particles sharing a stencil
//   summed by shuffles first (warp), or additionally summed in a shared-memory tile of the
//   block's stencil box and flushed once per node (tile; blocks whose box is too large fall
//   back to warp).
// - The grid kernel clears mass, momentum and force after using them, so no memset per step,
//   and returns at once on nodes no particle reached.
// - G2P: fused (kinematics and the whole constitutive update per thread), or split into a pass
//   of kinematics and elastic updates that lists the plastic points and a pass of their full
//   updates (CudaOptions::g2p_split; auto from two waves of the fused kernel up).
#pragma once

#include <cuda_runtime.h>

#include <cub/device/device_radix_sort.cuh>

#include <algorithm>
#include <climits>
#include <limits>
#include <cstdio>
#include <cstring>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include <granflow/mpm/binning.hpp>

#include "runner_common.hpp"

namespace granflow::mpm {
namespace {

void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess) throw std::runtime_error(std::string("CUDA error in ") + what + ": " + cudaGetErrorString(e));
}

constexpr unsigned kFullMask = 0xffffffffu;
constexpr int kP2GBlock = 128;
// Blocks of P2G per SM the compiler must fit: float storage at most 96 registers (20 warps/SM).
// 3D slab, fp32 (H200): 3,545 instead of 3,789 us per step at 105 registers; 80 registers
// (24 warps/SM, 104 B of spills) 3,691 us. Double: no cap (102 registers in 2D, 153 in 3D).
template <class S>
constexpr int p2g_min_blocks() { return sizeof(S) == 4 ? 5 : 1; }
constexpr int kGridBlock = 256;
constexpr int kAuxBlock = 256;
constexpr int kSplitBlock = 128;  // first pass of the split G2P
// Blocks of the split's first pass per SM the compiler must fit. An fp32 update: 6 (at most 80
// registers, 24 warps/SM, 52-76 B of spills): 3D slab (H200) 3,787 us per step for G2P against
// 4,098 at 96 registers and 4,483 at 118. fp64: 3 (156-168 registers, 12 warps/SM); with
// --g2p-regcap 4 (128 registers, 136 B of spills; no faster on the 1 mm column).
template <class MS>
constexpr int elastic_min_blocks(bool cap) { return sizeof(MS) == 4 ? 6 : (cap ? 4 : 3); }

// Shared-memory tile of P2G: at most this many nodes (a block's stencil box is about 60).
template <int D>
constexpr int tile_nodes() { return D == 2 ? 512 : 384; }

// Device-resident state of a span (span.hpp has the rules). The host writes it at the start
// and reads it back at the end; in between the last block of each step's final kernel
// advances it.
struct SpanControl {
  double t, dt, dt_max, t_land, t_until, flip, damping;
  long long max_steps;
  int adaptive;
  int active;              // the current step runs (0: span over or failed)
  double h;                // size of the current step
  double h_last;           // size of the last step taken
  long long steps;         // steps taken (a failed one included)
  unsigned long long bad;  // pack_bad of the first bad particle, kNoBadParticle: none
  unsigned long long lim;  // dt_limit_bits of the smallest stable step of the current step
  unsigned long long deferred;  // split G2P: points of the span's steps that needed the plastic pass
  unsigned int blocks_done;
};

enum P2GMode : int { kP2GAtomic = 0, kP2GWarp = 1, kP2GTile = 2 };

// The step's parameters with the span's step size, FLIP fraction and damping.
template <int D, class S, class Model>
__device__ __forceinline__ StepParams<D, S, Model> with_span(const StepParams<D, S, Model>& sp0, const SpanControl* c) {
  StepParams<D, S, Model> sp = sp0;
  sp.dt = S(c->h);
  sp.flip = S(c->flip);
  sp.damping = S(c->damping);
  sp.want_dt_limit = c->adaptive;
  sp.t = c->t;
  return sp;
}

// ---- P2G ---------------------------------------------------------------------------------

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
template <int D, class S, class Model, class Shape, int kMode>
__global__ void __launch_bounds__(kP2GBlock, p2g_min_blocks<S>())
    p2g_kernel(ParticleView<S> pv, GridView<S> gv, StepParams<D, S, Model> sp, const SpanControl* ctl,
               long* bin_keys) {
  static_assert(GridLayout<D>::M == 0 && GridLayout<D>::P == 1 && GridLayout<D>::F == 1 + D, "field order");
  constexpr int NC = 1 + 2 * D;
  constexpr int K = Shape::K;
  if (!ctl->active) return;
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  const bool valid = p < pv.n;
  P2GParticle<D, S> q{};
  int base[D] = {};
  if (valid) {
    q = p2g_load<D, S, Model>(pv, p, sp);
    stencil_base<D, S, Shape>(q.xi, sp.grid, base);  // G2P of the last step checked it is on the grid
    if (bin_keys) bin_keys[p] = sp.grid.linear(base);  // bin of the particle (volumetric averaging)
  }
  auto to_global = [&](const int* I, const S* c) {
    const long n = sp.grid.linear(I);
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
    const long key = valid ? sp.grid.linear(base) : -1 - static_cast<long>(threadIdx.x);
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
template <int D, class S, class Model, bool kBoundary, bool kContacts>
__global__ void grid_kernel(GridView<S> gv, StepParams<D, S, Model> sp0, const SpanControl* ctl) {
  if (!ctl->active) return;
  const long I = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (I >= gv.n) return;
  if (gv.f(GridLayout<D>::M, I) == S(0)) return;
  const StepParams<D, S, Model> sp = with_span(sp0, ctl);
  grid_update_node<D, S, Model, kBoundary, kContacts>(gv, I, sp);
  for (int f = 0; f < 1 + 2 * D; ++f) gv.f(f, I) = S(0);
}

// ---- G2P and the end of a step -----------------------------------------------------------

// Block min-reduction of the stable step into ctl->lim (every thread of the block calls it).
__device__ __forceinline__ void reduce_dt_limit(SpanControl* ctl, double lim) {
  __shared__ unsigned long long s_min[32];
  unsigned long long b = dt_limit_bits(lim);
  for (int o = 16; o > 0; o >>= 1) {
    const unsigned long long other = __shfl_down_sync(kFullMask, b, o);
    b = other < b ? other : b;
  }
  if ((threadIdx.x & 31) == 0) s_min[threadIdx.x >> 5] = b;
  __syncthreads();
  if (threadIdx.x == 0) {
    for (unsigned w = 1; w < (blockDim.x + 31) / 32; ++w) b = s_min[w] < b ? s_min[w] : b;
    atomicMin(&ctl->lim, b);
  }
}

// Called by every thread of every block of a step's final kernel (after its particle work).
// Reduces the stable step, and the last block to finish records the step and plans the next
// (and clears `counter`, the deferred-point count the kernel's blocks read at their start).
__device__ __forceinline__ void finish_step(SpanControl* ctl, double lim, int want_lim,
                                            unsigned* counter = nullptr) {
  if (want_lim) reduce_dt_limit(ctl, lim);
  __threadfence();
  __syncthreads();
  __shared__ bool s_last;
  if (threadIdx.x == 0) s_last = atomicAdd(&ctl->blocks_done, 1u) == gridDim.x - 1;
  __syncthreads();
  if (!s_last || threadIdx.x != 0) return;
  __threadfence();
  SpanControl& c = *ctl;
  const unsigned long long bad = atomicOr(&c.bad, 0ull);
  const unsigned long long lb = atomicOr(&c.lim, 0ull);
  c.steps += 1;
  c.h_last = c.h;
  if (bad != kNoBadParticle) {
    c.active = 0;
  } else {
    c.t = __dadd_rn(c.t, c.h);
    if (c.adaptive) c.dt = span_next_dt(dt_limit_value(lb), c.dt_max);
    if (span_reached(c.t, c.t_until) || c.steps >= c.max_steps)
      c.active = 0;
    else
      c.h = span_step_size(c.t, c.dt, c.t_land);
  }
  c.lim = dt_limit_bits(1e300);
  c.blocks_done = 0;
  if (counter) {
    c.deferred += *counter;
    *counter = 0;
  }
}

template <int D, class S, class Model, class Shape, int kMaxThreads, int kMinBlocks>
__global__ void __launch_bounds__(kMaxThreads, kMinBlocks)
    g2p_kernel(ParticleView<S> pv, GridView<S> gv, StepParams<D, S, Model> sp0, SpanControl* ctl,
               const std::uint32_t* ids, std::uint32_t* upd_info) {
  if (!ctl->active) return;
  const StepParams<D, S, Model> sp = with_span(sp0, ctl);
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  S lim = S(1e300);
  if (p < pv.n) {
    const std::uint32_t st = g2p_particle<D, S, Model, Shape>(pv, gv, p, sp, &lim, &upd_info[p]);
    if (st) atomicMin(&ctl->bad, pack_bad(ids[p], st));
  }
  finish_step(ctl, double(lim), sp.want_dt_limit);
}

// G2P split in two passes (CudaOptions::g2p_split). The first does the kinematics and the
// elastic part of every update (UpdatePart::ElasticOnly: half the registers of the full update)
// and lists the points whose step is plastic; the second runs the full update of the listed
// points only, packed into warps, so that elastic points wait for no return map and a warp's
// returns are of points that all need one. Each point gets the fused kernel's update (test
// PhaseTransition.ElasticOnlyUpdateIsTheFullUpdateOrDefersPlasticSteps).
template <int D, class S, class Model, class Shape, int kMinBlocks>
__global__ void __launch_bounds__(kSplitBlock, kMinBlocks)
    g2p_elastic_kernel(ParticleView<S> pv, GridView<S> gv, StepParams<D, S, Model> sp0, SpanControl* ctl,
                       const std::uint32_t* ids, std::uint32_t* upd_info, std::uint32_t* deferred,
                       unsigned* n_deferred) {
  if (!ctl->active) return;
  const StepParams<D, S, Model> sp = with_span(sp0, ctl);
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  S lim = S(1e300);
  bool defer = false;
  if (p < pv.n) {
    const std::uint32_t st =
        g2p_particle<D, S, Model, Shape, UpdatePart::ElasticOnly>(pv, gv, p, sp, &lim, &upd_info[p]);
    defer = st == kDeferredPoint;
    if (st && !defer) atomicMin(&ctl->bad, pack_bad(ids[p], st));
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

template <int D, class S, class Model, int kMaxThreads, int kMinBlocks>
__global__ void __launch_bounds__(kMaxThreads, kMinBlocks)
    g2p_plastic_kernel(ParticleView<S> pv, StepParams<D, S, Model> sp0, SpanControl* ctl, const std::uint32_t* ids,
                       std::uint32_t* upd_info, const std::uint32_t* deferred, unsigned* n_deferred) {
  if (!ctl->active) return;
  const StepParams<D, S, Model> sp = with_span(sp0, ctl);
  const long i = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  S lim = S(1e300);
  if (i < static_cast<long>(*n_deferred)) {
    const long p = deferred[i];
    const std::uint32_t st = constitutive_particle<D, S, Model>(pv, p, sp, S(NAN), &lim, &upd_info[p]);
    if (st) atomicMin(&ctl->bad, pack_bad(ids[p], st));
  }
  finish_step(ctl, double(lim), sp.want_dt_limit, n_deferred);
}

// Split G2P for volumetric averaging: kinematics and bin sums, then the constitutive update.
template <int D, class S, class Model, class Shape>
__global__ void g2p_kinematics_kernel(ParticleView<S> pv, GridView<S> gv, StepParams<D, S, Model> sp0,
                                      SpanControl* ctl, const std::uint32_t* ids, const long* keys, S* bin_v,
                                      S* bin_vtr, std::uint32_t* status) {
  if (!ctl->active) return;
  const StepParams<D, S, Model> sp = with_span(sp0, ctl);
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (p >= pv.n) return;
  const std::uint32_t st = g2p_kinematics<D, S, Model, Shape>(pv, gv, p, sp);
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

template <int D, class S, class Model, int kMaxThreads, int kMinBlocks>
__global__ void __launch_bounds__(kMaxThreads, kMinBlocks)
    constitutive_kernel(ParticleView<S> pv, StepParams<D, S, Model> sp0, SpanControl* ctl, const std::uint32_t* ids,
                        const long* keys, const S* bin_v, const S* bin_vtr, std::uint32_t* status,
                        std::uint32_t* upd_info) {
  if (!ctl->active) return;
  const StepParams<D, S, Model> sp = with_span(sp0, ctl);
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  S lim = S(1e300);
  if (p < pv.n && status[p] == 0) {  // else the kinematics already failed here
    const long b = keys[p];
    const S tr_bar = bin_v[b] > S(0) ? bin_vtr[b] / bin_v[b] : S(0);
    const std::uint32_t st = constitutive_particle<D, S, Model>(pv, p, sp, tr_bar, &lim, &upd_info[p]);
    status[p] = st;
    if (st) atomicMin(&ctl->bad, pack_bad(ids[p], st));
  }
  finish_step(ctl, double(lim), sp.want_dt_limit);
}

// ---- particle order ----------------------------------------------------------------------

template <int D, class S, class Shape, bool kColl>
__global__ void sort_key_kernel(ParticleView<S> pv, GridDesc<D, S> g, std::uint32_t* keys, std::uint32_t* slots) {
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (p >= pv.n) return;
  S xi[D];
  int base[D];
  particle_base<D, S, Shape, kColl>(pv, p, g, xi, base);
  keys[p] = static_cast<std::uint32_t>(sort_key<D>(base, g.nodes));
  slots[p] = static_cast<std::uint32_t>(p);
}

template <class S>
__global__ void gather_kernel(ParticleView<S> src, ParticleView<S> dst, int nfields, const std::uint32_t* perm,
                              const std::uint32_t* ids_src, std::uint32_t* ids_dst) {
  const long i = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (i >= src.n) return;
  const long from = perm[i];
  gather_slot(src, dst, nfields, i, from);
  ids_dst[i] = ids_src[from];
}

__global__ void inverse_kernel(const std::uint32_t* ids, std::uint32_t* inv, long n) {
  const long i = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (i < n) inv[ids[i]] = static_cast<std::uint32_t>(i);
}

__global__ void iota_kernel(std::uint32_t* a, long n) {
  const long i = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (i < n) a[i] = static_cast<std::uint32_t>(i);
}

struct FieldList {
  int f[32];
  int n;
};

// out[k][ids[i]] = field fl.f[k] of slot i: the listed fields in the original order.
template <class S>
__global__ void unpermute_kernel(ParticleView<S> src, const std::uint32_t* ids, FieldList fl, S* out) {
  const long i = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (i >= src.n) return;
  const long o = ids[i];
  for (int k = 0; k < fl.n; ++k) out[k * src.n + o] = src.f(fl.f[k], i);
}

// out[f][j] = field f of the particle of original index sub[j].
template <class S>
__global__ void subset_kernel(ParticleView<S> src, const std::uint32_t* inv, const long* sub, long m, int nfields,
                              S* out) {
  const long j = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (j >= m) return;
  const long i = inv[sub[j]];
  for (int f = 0; f < nfields; ++f) out[f * m + j] = src.f(f, i);
}

// ---- runner ------------------------------------------------------------------------------

template <class T>
T* device_alloc(size_t n) {
  T* p = nullptr;
  check(cudaMalloc(&p, n * sizeof(T) + 16), "cudaMalloc");
  return p;
}

unsigned blocks_for(long n, int block) { return static_cast<unsigned>((n + block - 1) / block); }

template <class K>
std::string kernel_info(const char* name, K* kernel, int block) {
  cudaFuncAttributes a{};
  if (cudaFuncGetAttributes(&a, reinterpret_cast<const void*>(kernel)) != cudaSuccess) return "";
  int per_sm = 0, min_grid = 0, best = 0;
  cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, kernel, block, 0);
  cudaOccupancyMaxPotentialBlockSize(&min_grid, &best, kernel, 0, 0);
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "  %s: %d registers, %zu B local (spills/stack), %zu B shared; block %d -> %d warps/SM "
                "(occupancy API suggests block %d)\n",
                name, a.numRegs, a.localSizeBytes, a.sharedSizeBytes, block, per_sm * block / 32, best);
  return buf;
}

template <int D, class S, class Model, class Shape, bool kBoundary>
class CudaRunner final : public Runner {
  using G = GridLayout<D>;
  using Lay = ParticleLayout<D, Model::kCollisional>;
  static constexpr bool kColl = Model::kCollisional;
  static constexpr int kElastic = elastic_min_blocks<typename Model::Scalar>(false);
  static constexpr int kElasticCap = elastic_min_blocks<typename Model::Scalar>(true);

 public:
  CudaRunner(const SceneSetup& su, const CudaOptions& opt)
      : sp_(detail::step_params<D, S, Model>(su)), n_(su.particles.n), opt_(opt) {
    if (n_ <= 0 || n_ >= (1L << 31)) throw std::runtime_error("CUDA backend: particle count out of range");
    if (opt_.graph_steps < 1) opt_.graph_steps = 1;
    while (opt_.graph_steps & (opt_.graph_steps - 1)) opt_.graph_steps &= opt_.graph_steps - 1;  // power of two
    if (opt_.g2p_reg_cap && opt_.g2p_block > 128) opt_.g2p_block = 128;
    if (opt_.g2p_block < 32 || opt_.g2p_block > 256 || opt_.g2p_block % 32) opt_.g2p_block = 128;
    if (sort_key_bound<D>(sp_.grid.nodes) > (1ull << 32)) opt_.sort_every = 0;  // keys are 32 bits
    key_bits_ = 1;
    while (key_bits_ < 32 && (1ull << key_bits_) < sort_key_bound<D>(sp_.grid.nodes)) ++key_bits_;

    check(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking), "cudaStreamCreate");
    const size_t nf = static_cast<size_t>(Lay::N) * n_;
    const long nn = sp_.grid.n_nodes;
    part_ = device_alloc<S>(nf);
    alt_ = device_alloc<S>(nf);
    grid_ = device_alloc<S>(static_cast<size_t>(G::N) * nn);
    status_ = device_alloc<std::uint32_t>(n_);
    info_ = device_alloc<std::uint32_t>(n_);
    ids_ = device_alloc<std::uint32_t>(n_);
    ids_alt_ = device_alloc<std::uint32_t>(n_);
    inv_ = device_alloc<std::uint32_t>(n_);
    if (!sp_.vol_avg && use_split()) {
      deferred_ = device_alloc<std::uint32_t>(n_);
      n_deferred_ = device_alloc<unsigned>(1);
      check(cudaMemset(n_deferred_, 0, sizeof(unsigned)), "clear deferred count");
    }
    if (sp_.vol_avg) {
      keys_ = device_alloc<long>(n_);
      bins_ = device_alloc<S>(2 * static_cast<size_t>(nn));
    }
    if (opt_.sort_every > 0) {
      for (auto*& a : sort_buf_) a = device_alloc<std::uint32_t>(n_);
      check(cub::DeviceRadixSort::SortPairs(nullptr, sort_tmp_bytes_, sort_buf_[0], sort_buf_[1], sort_buf_[2],
                                            sort_buf_[3], static_cast<int>(n_), 0, key_bits_, stream_),
            "sort size");
      sort_tmp_ = device_alloc<unsigned char>(sort_tmp_bytes_);
    }
    ctl_ = device_alloc<SpanControl>(1);
    check(cudaMallocHost(&ctl_in_, sizeof(SpanControl)), "cudaMallocHost");
    check(cudaMallocHost(&ctl_out_, sizeof(SpanControl)), "cudaMallocHost");
    for (const auto& m : su.stage_masks) {
      std::uint8_t* d = nullptr;
      if (!m.empty()) {
        d = device_alloc<std::uint8_t>(m.size());
        check(cudaMemcpy(d, m.data(), m.size(), cudaMemcpyHostToDevice), "upload masks");
      }
      masks_.push_back(d);
      contacts_.push_back(stage_has_contacts(su, static_cast<int>(masks_.size()) - 1));
    }
    for (auto& e : ev_) check(cudaEventCreate(&e), "cudaEventCreate");
    preload();
    load(su.particles);
    set_stage(0, 0.0, su.scene.flip);
  }

  ~CudaRunner() override {
    cudaStreamSynchronize(stream_);
    for (auto& [k, g] : graphs_) cudaGraphExecDestroy(g);
    for (void* p : {static_cast<void*>(part_), static_cast<void*>(alt_), static_cast<void*>(grid_),
                    static_cast<void*>(status_), static_cast<void*>(info_), static_cast<void*>(ids_),
                    static_cast<void*>(ids_alt_), static_cast<void*>(inv_), static_cast<void*>(keys_),
                    static_cast<void*>(bins_), static_cast<void*>(sort_tmp_), static_cast<void*>(ctl_),
                    static_cast<void*>(sub_ids_), static_cast<void*>(sub_out_), static_cast<void*>(deferred_),
                    static_cast<void*>(n_deferred_)})
      cudaFree(p);
    for (auto* a : sort_buf_) cudaFree(a);
    for (auto* m : masks_) cudaFree(m);
    cudaFreeHost(ctl_in_);
    cudaFreeHost(ctl_out_);
    if (host_) cudaFreeHost(host_);
    for (auto& e : ev_) cudaEventDestroy(e);
    cudaStreamDestroy(stream_);
  }

  void set_stage(int stage, double damping, double flip) override {
    stage_ = stage;
    damping_ = damping;
    flip_ = flip;
  }

  StepResult step(double dt, bool want_dt_limit) override {
    Span s;
    s.max_steps = 1;
    s.t = t_;
    s.dt = dt;
    s.adaptive = want_dt_limit;
    s.dt_max = std::numeric_limits<double>::infinity();  // next dt = the limit itself
    const SpanResult r = advance_span(s);
    StepResult out = step_result(r);
    if (want_dt_limit && r.ok) out.dt_limit = r.dt;
    return out;
  }

  SpanResult advance_span(const Span& s) override {
    SpanControl& c = *ctl_in_;
    std::memset(&c, 0, sizeof c);
    c.t = s.t;
    c.dt = s.dt;
    c.dt_max = s.dt_max;
    c.t_land = s.t_land;
    c.t_until = s.t_until;
    c.flip = flip_;
    c.damping = damping_;
    c.max_steps = s.max_steps;
    c.adaptive = s.adaptive ? 1 : 0;
    c.active = s.max_steps > 0 ? 1 : 0;
    c.h = span_step_size(s.t, s.dt, s.t_land);
    c.bad = kNoBadParticle;
    c.lim = dt_limit_bits(1e300);
    check(cudaMemcpyAsync(ctl_, ctl_in_, sizeof c, cudaMemcpyHostToDevice, stream_), "span start");
    check(cudaEventRecord(ev_[kSpan0], stream_), "event");
    if (s.timing)
      run_timed(s.max_steps);
    else
      run_queued(s.max_steps);
    check(cudaEventRecord(ev_[kSpan1], stream_), "event");
    check(cudaMemcpyAsync(ctl_out_, ctl_, sizeof c, cudaMemcpyDeviceToHost, stream_), "span end");
    check(cudaStreamSynchronize(stream_), "span");
    check(cudaGetLastError(), "span kernels");
    float ms = 0;
    cudaEventElapsedTime(&ms, ev_[kSpan0], ev_[kSpan1]);
    const SpanControl& o = *ctl_out_;
    times_.device += 1e-3 * ms;
    times_.span_steps += o.steps;
    times_.deferred += static_cast<long>(o.deferred);
    t_ = o.t;
    SpanResult r;
    r.steps = o.steps;
    r.t = o.t;
    r.dt = o.dt;
    r.h_last = o.h_last;
    if (o.bad != kNoBadParticle) {
      r.ok = false;
      r.particle = static_cast<long>(o.bad >> 32);
      r.status = static_cast<std::uint32_t>(o.bad & 0xffffffffu);
    }
    return r;
  }

  void frame(Frame& out, bool diagnostics, const std::vector<long>& subset) override {
    if (diagnostics) {
      std::vector<S> host = fetch_all();
      detail::make_frame<D, S, Model>(host, n_, sp_.mp, out, diagnostics, subset);
      return;
    }
    // light frame: x, v and sqrt(T) of every particle, full records of the subset only
    FieldList fl{};
    for (int d = 0; d < D; ++d) {
      fl.f[fl.n++] = Lay::X + d;
      fl.f[fl.n++] = Lay::V + d;
    }
    if constexpr (kColl) fl.f[fl.n++] = Lay::SQT;
    const S* h = fetch(fl);
    out.n = n_;
    out.dim = D;
    out.x.resize(D * n_);
    out.v.resize(D * n_);
    for (int d = 0; d < D; ++d) {
      std::copy(h + (2 * d) * n_, h + (2 * d + 1) * n_, out.x.begin() + d * n_);
      std::copy(h + (2 * d + 1) * n_, h + (2 * d + 2) * n_, out.v.begin() + d * n_);
    }
    out.T.assign(n_, 0.0);
    if constexpr (kColl) {
      const S* s = h + 2 * D * n_;
      for (long i = 0; i < n_; ++i) out.T[i] = s[i] * s[i];
    }
    for (auto* f : {&out.p, &out.q, &out.eps_pd, &out.eta_c, &out.K_col, &out.e, &out.sxx, &out.syy, &out.sxy})
      f->clear();
    out.subset.clear();
    if (subset.empty()) return;
    // the subset's records in subset order, evaluated by the host code of make_frame
    const long m = static_cast<long>(subset.size());
    for (long i : subset)
      if (i < 0 || i >= n_) throw std::runtime_error("frame: particle index out of range");
    if (m > sub_cap_) {
      cudaFree(sub_ids_);
      cudaFree(sub_out_);
      sub_ids_ = device_alloc<long>(m);
      sub_out_ = device_alloc<S>(static_cast<size_t>(Lay::N) * m);
      sub_cap_ = m;
    }
    std::vector<S> small(static_cast<size_t>(Lay::N) * m);
    check(cudaMemcpyAsync(sub_ids_, subset.data(), m * sizeof(long), cudaMemcpyHostToDevice, stream_), "subset");
    subset_kernel<S><<<blocks_for(m, kAuxBlock), kAuxBlock, 0, stream_>>>(part_view(), inv_, sub_ids_, m, Lay::N,
                                                                          sub_out_);
    check(cudaMemcpyAsync(small.data(), sub_out_, small.size() * sizeof(S), cudaMemcpyDeviceToHost, stream_),
          "subset");
    check(cudaStreamSynchronize(stream_), "subset");
    std::vector<long> all(m);
    for (long j = 0; j < m; ++j) all[j] = j;
    Frame tmp;
    detail::make_frame<D, S, Model>(small, m, sp_.mp, tmp, false, all);
    out.subset = std::move(tmp.subset);
  }

  void download(HostParticles& out) override { detail::unpack<D, S, kColl>(fetch_all(), n_, out); }
  void upload(const HostParticles& in) override {
    detail::check_upload(in, n_, D);
    load(in);
  }
  PhaseTimes times() const override { return times_; }
  void reset_times() override { times_ = PhaseTimes{}; }
  std::string device() const override {
    int dev = 0;
    cudaGetDevice(&dev);
    cudaDeviceProp prop;
    cudaGetDeviceProperties(&prop, dev);
    return std::string("CUDA ") + prop.name + " (sm_" + std::to_string(prop.major) + std::to_string(prop.minor) + ")";
  }
  std::string config() const override {
    std::string s = "CUDA options: " + describe(opt_) + "\n";
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
      s += kernel_info(p2g_name, p2g_kernel<D, S, Model, Shape, kP2GAtomic>, kP2GBlock);
    else if (opt_.p2g == CudaOptions::P2G::Warp)
      s += kernel_info(p2g_name, p2g_kernel<D, S, Model, Shape, kP2GWarp>, kP2GBlock);
    else
      s += kernel_info(p2g_name, p2g_kernel<D, S, Model, Shape, kP2GTile>, kP2GBlock);
    s += kernel_info("grid update", grid_kernel<D, S, Model, kBoundary, false>, kGridBlock);
    if (split()) {
      if (opt_.g2p_reg_cap)
        s += kernel_info("G2P + elastic part", g2p_elastic_kernel<D, S, Model, Shape, kElasticCap>, kSplitBlock);
      else
        s += kernel_info("G2P + elastic part", g2p_elastic_kernel<D, S, Model, Shape, kElastic>, kSplitBlock);
      s += kernel_info("plastic return of the deferred points", g2p_plastic_kernel<D, S, Model, 256, 1>,
                       opt_.g2p_block);
    } else if (!sp_.vol_avg) {
      if (opt_.g2p_reg_cap)
        s += kernel_info("G2P + constitutive", g2p_kernel<D, S, Model, Shape, 128, 3>, opt_.g2p_block);
      else
        s += kernel_info("G2P + constitutive", g2p_kernel<D, S, Model, Shape, 256, 1>, opt_.g2p_block);
    } else {
      s += kernel_info("G2P kinematics", g2p_kinematics_kernel<D, S, Model, Shape>, kP2GBlock);
      if (opt_.g2p_reg_cap)
        s += kernel_info("constitutive", constitutive_kernel<D, S, Model, 128, 3>, opt_.g2p_block);
      else
        s += kernel_info("constitutive", constitutive_kernel<D, S, Model, 256, 1>, opt_.g2p_block);
    }
    return s;
  }
  long particles() const override { return n_; }
  long nodes() const override { return sp_.grid.n_nodes; }

 private:
  enum { kP2G0, kGrid0, kG2P0, kG2P1, kSort0, kSort1, kSpan0, kSpan1, kNumEvents };

  ParticleView<S> part_view() const { return ParticleView<S>{part_, n_}; }
  bool split() const { return deferred_ != nullptr; }

  // Split G2P: as asked, or (auto) from two waves of the fused kernel up, where the step is
  // throughput-bound rather than bound by one point's latency.
  bool use_split() {
    if (opt_.g2p_split != CudaOptions::Split::Auto) return opt_.g2p_split == CudaOptions::Split::On;
    int dev = 0, sms = 0, per_sm = 0;
    check(cudaGetDevice(&dev), "cudaGetDevice");
    check(cudaDeviceGetAttribute(&sms, cudaDevAttrMultiProcessorCount, dev), "SM count");
    if (opt_.g2p_reg_cap)
      check(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, g2p_kernel<D, S, Model, Shape, 128, 3>,
                                                          opt_.g2p_block, 0), "occupancy");
    else
      check(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, g2p_kernel<D, S, Model, Shape, 256, 1>,
                                                          opt_.g2p_block, 0), "occupancy");
    fused_waves_ = double(n_) / (double(sms) * std::max(1, per_sm) * opt_.g2p_block);
    return fused_waves_ >= 2.0;
  }

  // Loads the step kernels now (lazy module loading would otherwise load them during the
  // first graph capture, which older drivers refuse).
  void preload() const {
    cudaFuncAttributes a;
    const void* k[] = {reinterpret_cast<const void*>(p2g_kernel<D, S, Model, Shape, kP2GAtomic>),
                       reinterpret_cast<const void*>(p2g_kernel<D, S, Model, Shape, kP2GWarp>),
                       reinterpret_cast<const void*>(p2g_kernel<D, S, Model, Shape, kP2GTile>),
                       reinterpret_cast<const void*>(grid_kernel<D, S, Model, kBoundary, false>),
                       reinterpret_cast<const void*>(grid_kernel<D, S, Model, kBoundary, kBoundary>),
                       reinterpret_cast<const void*>(g2p_kernel<D, S, Model, Shape, 256, 1>),
                       reinterpret_cast<const void*>(g2p_kernel<D, S, Model, Shape, 128, 3>),
                       reinterpret_cast<const void*>(g2p_kinematics_kernel<D, S, Model, Shape>),
                       reinterpret_cast<const void*>(constitutive_kernel<D, S, Model, 256, 1>),
                       reinterpret_cast<const void*>(constitutive_kernel<D, S, Model, 128, 3>),
                       reinterpret_cast<const void*>(g2p_elastic_kernel<D, S, Model, Shape, kElastic>),
                       reinterpret_cast<const void*>(g2p_elastic_kernel<D, S, Model, Shape, kElasticCap>),
                       reinterpret_cast<const void*>(g2p_plastic_kernel<D, S, Model, 256, 1>)};
    for (const void* f : k) check(cudaFuncGetAttributes(&a, f), "load kernels");
  }

  // Particle state from the host (the set-up, or a checkpoint through upload()). The buffer keeps its address, so captured graphs stay valid; the order is the
  // original one again, and the grid is cleared (a failed step may have left non-finite node
  // velocities, which nodes out of reach would otherwise pass on weighted by zero).
  void load(const HostParticles& hp) {
    if (hp.n != n_) throw std::runtime_error("CUDA backend: particle count differs from the set-up");
    const std::vector<S> host = detail::pack<D, S, kColl>(hp);
    check(cudaMemcpyAsync(part_, host.data(), host.size() * sizeof(S), cudaMemcpyHostToDevice, stream_),
          "upload particles");
    iota_kernel<<<blocks_for(n_, kAuxBlock), kAuxBlock, 0, stream_>>>(ids_, n_);
    iota_kernel<<<blocks_for(n_, kAuxBlock), kAuxBlock, 0, stream_>>>(inv_, n_);
    // the grid kernel keeps mass, momentum and force zero between steps; velocities of nodes
    // no particle reaches are weighed by zero and must only be finite
    check(cudaMemsetAsync(grid_, 0, sizeof(S) * G::N * sp_.grid.n_nodes, stream_), "clear grid");
    check(cudaStreamSynchronize(stream_), "upload particles");
    since_sort_ = opt_.sort_every;  // sort before the first step
  }

  // Queues one step (kernels only: capturable).
  void enqueue_step(bool timed) {
    const long nn = sp_.grid.n_nodes;
    const ParticleView<S> pv = part_view();
    const GridView<S> gv{grid_, nn, masks_[stage_]};
    const unsigned pb = blocks_for(n_, kP2GBlock);
    const unsigned gb = blocks_for(nn, kGridBlock);
    const unsigned cb = blocks_for(n_, opt_.g2p_block);
    long* bk = sp_.vol_avg ? keys_ : nullptr;
    if (timed) cudaEventRecord(ev_[kP2G0], stream_);
    switch (opt_.p2g) {
      case CudaOptions::P2G::Atomic:
        p2g_kernel<D, S, Model, Shape, kP2GAtomic><<<pb, kP2GBlock, 0, stream_>>>(pv, gv, sp_, ctl_, bk);
        break;
      case CudaOptions::P2G::Warp:
        p2g_kernel<D, S, Model, Shape, kP2GWarp><<<pb, kP2GBlock, 0, stream_>>>(pv, gv, sp_, ctl_, bk);
        break;
      case CudaOptions::P2G::Tile:
        p2g_kernel<D, S, Model, Shape, kP2GTile><<<pb, kP2GBlock, 0, stream_>>>(pv, gv, sp_, ctl_, bk);
        break;
    }
    if (timed) cudaEventRecord(ev_[kGrid0], stream_);
    if (kBoundary && contacts_[stage_])  // friction or a lifting gate (boundary.hpp)
      grid_kernel<D, S, Model, kBoundary, kBoundary><<<gb, kGridBlock, 0, stream_>>>(gv, sp_, ctl_);
    else
      grid_kernel<D, S, Model, kBoundary, false><<<gb, kGridBlock, 0, stream_>>>(gv, sp_, ctl_);
    if (timed) cudaEventRecord(ev_[kG2P0], stream_);
    if (split()) {
      const unsigned eb = blocks_for(n_, kSplitBlock);
      if (opt_.g2p_reg_cap)
        g2p_elastic_kernel<D, S, Model, Shape, kElasticCap>
            <<<eb, kSplitBlock, 0, stream_>>>(pv, gv, sp_, ctl_, ids_, info_, deferred_, n_deferred_);
      else
        g2p_elastic_kernel<D, S, Model, Shape, kElastic>
            <<<eb, kSplitBlock, 0, stream_>>>(pv, gv, sp_, ctl_, ids_, info_, deferred_, n_deferred_);
      g2p_plastic_kernel<D, S, Model, 256, 1><<<cb, opt_.g2p_block, 0, stream_>>>(
          pv, sp_, ctl_, ids_, info_, deferred_, n_deferred_);
    } else if (!sp_.vol_avg) {
      if (opt_.g2p_reg_cap)
        g2p_kernel<D, S, Model, Shape, 128, 3><<<cb, opt_.g2p_block, 0, stream_>>>(pv, gv, sp_, ctl_, ids_, info_);
      else
        g2p_kernel<D, S, Model, Shape, 256, 1><<<cb, opt_.g2p_block, 0, stream_>>>(pv, gv, sp_, ctl_, ids_, info_);
    } else {
      check(cudaMemsetAsync(bins_, 0, sizeof(S) * 2 * nn, stream_), "clear bins");
      g2p_kinematics_kernel<D, S, Model, Shape><<<pb, kP2GBlock, 0, stream_>>>(pv, gv, sp_, ctl_, ids_, keys_, bins_,
                                                                               bins_ + nn, status_);
      if (opt_.g2p_reg_cap)
        constitutive_kernel<D, S, Model, 128, 3><<<cb, opt_.g2p_block, 0, stream_>>>(
            pv, sp_, ctl_, ids_, keys_, bins_, bins_ + nn, status_, info_);
      else
        constitutive_kernel<D, S, Model, 256, 1><<<cb, opt_.g2p_block, 0, stream_>>>(
            pv, sp_, ctl_, ids_, keys_, bins_, bins_ + nn, status_, info_);
    }
    if (timed) cudaEventRecord(ev_[kG2P1], stream_);
  }

  // Reorders the particles by cell key (binning.hpp): slot i receives slot perm[i].
  void enqueue_sort() {
    const unsigned b = blocks_for(n_, kAuxBlock);
    sort_key_kernel<D, S, Shape, kColl><<<b, kAuxBlock, 0, stream_>>>(part_view(), sp_.grid, sort_buf_[0], sort_buf_[2]);
    check(cub::DeviceRadixSort::SortPairs(sort_tmp_, sort_tmp_bytes_, sort_buf_[0], sort_buf_[1], sort_buf_[2],
                                          sort_buf_[3], static_cast<int>(n_), 0, key_bits_, stream_),
          "sort");
    gather_kernel<S><<<b, kAuxBlock, 0, stream_>>>(part_view(), ParticleView<S>{alt_, n_}, Lay::N, sort_buf_[3], ids_,
                                                   ids_alt_);
    check(cudaMemcpyAsync(part_, alt_, sizeof(S) * Lay::N * n_, cudaMemcpyDeviceToDevice, stream_), "sort copy");
    check(cudaMemcpyAsync(ids_, ids_alt_, sizeof(std::uint32_t) * n_, cudaMemcpyDeviceToDevice, stream_), "sort copy");
    inverse_kernel<<<b, kAuxBlock, 0, stream_>>>(ids_, inv_, n_);
  }

  bool sort_due() const { return opt_.sort_every > 0 && since_sort_ >= opt_.sort_every; }

  // Steps up to the next sort, at most `left`.
  long chunk_limit(long left) const {
    return opt_.sort_every > 0 ? std::min(left, static_cast<long>(opt_.sort_every) - since_sort_) : left;
  }

  // Graph of `steps` steps of the current stage; the first call of a stage captures every
  // chunk length (1, 2, 4, ... graph_steps) so that later spans only replay.
  cudaGraphExec_t graph_for(int steps) {
    const long key = static_cast<long>(stage_) * 4096 + steps;
    auto it = graphs_.find(key);
    if (it != graphs_.end()) return it->second;
    if (graphs_.find(static_cast<long>(stage_) * 4096 + 1) == graphs_.end())
      for (int c = 1; c <= opt_.graph_steps; c *= 2) capture(c);
    it = graphs_.find(key);
    return it != graphs_.end() ? it->second : capture(steps);
  }

  cudaGraphExec_t capture(int steps) {
    const long key = static_cast<long>(stage_) * 4096 + steps;
    check(cudaStreamBeginCapture(stream_, cudaStreamCaptureModeThreadLocal), "begin capture");
    try {
      for (int i = 0; i < steps; ++i) enqueue_step(false);
    } catch (...) {
      cudaGraph_t g = nullptr;
      cudaStreamEndCapture(stream_, &g);
      if (g) cudaGraphDestroy(g);
      throw;
    }
    cudaGraph_t g = nullptr;
    check(cudaStreamEndCapture(stream_, &g), "end capture");
    cudaGraphExec_t exec = nullptr;
    const cudaError_t e = cudaGraphInstantiate(&exec, g, 0);
    cudaGraphDestroy(g);
    check(e, "graph instantiate");
    graphs_[key] = exec;
    return exec;
  }

  // Production: the steps are queued (graph chunks of 2^k steps), sorted every sort_every.
  void run_queued(long nsteps) {
    long left = nsteps;
    while (left > 0) {
      if (sort_due()) {
        enqueue_sort();
        since_sort_ = 0;
      }
      long chunk = chunk_limit(left);
      if (opt_.graphs) {
        long c = 1;
        while (c * 2 <= std::min(chunk, static_cast<long>(opt_.graph_steps))) c *= 2;
        chunk = c;
        check(cudaGraphLaunch(graph_for(static_cast<int>(chunk)), stream_), "graph launch");
      } else {
        for (long i = 0; i < chunk; ++i) enqueue_step(false);
        check(cudaGetLastError(), "kernel launch");
      }
      since_sort_ += chunk;
      left -= chunk;
    }
  }

  // Benchmarks: every phase between events, a synchronisation per step; stops when the span does.
  void run_timed(long nsteps) {
    for (long i = 0; i < nsteps; ++i) {
      if (sort_due()) {
        cudaEventRecord(ev_[kSort0], stream_);
        enqueue_sort();
        cudaEventRecord(ev_[kSort1], stream_);
        since_sort_ = 0;
        check(cudaEventSynchronize(ev_[kSort1]), "sort");
        float ms = 0;
        cudaEventElapsedTime(&ms, ev_[kSort0], ev_[kSort1]);
        times_.sort += 1e-3 * ms;
      }
      enqueue_step(true);
      check(cudaGetLastError(), "kernel launch");
      check(cudaMemcpyAsync(ctl_out_, ctl_, sizeof(SpanControl), cudaMemcpyDeviceToHost, stream_), "step");
      check(cudaStreamSynchronize(stream_), "step");
      ++since_sort_;
      float ms[3];
      for (int k = 0; k < 3; ++k) cudaEventElapsedTime(&ms[k], ev_[kP2G0 + k], ev_[kP2G0 + k + 1]);
      times_.p2g += 1e-3 * ms[0];
      times_.grid += 1e-3 * ms[1];
      times_.g2p += 1e-3 * ms[2];
      ++times_.steps;
      if (!ctl_out_->active) break;
    }
  }

  // The listed fields of every particle in the original order, in pinned host memory.
  const S* fetch(const FieldList& fl) {
    if (!host_) check(cudaMallocHost(&host_, sizeof(S) * Lay::N * n_), "cudaMallocHost");
    unpermute_kernel<S><<<blocks_for(n_, kAuxBlock), kAuxBlock, 0, stream_>>>(part_view(), ids_, fl, alt_);
    check(cudaMemcpyAsync(host_, alt_, sizeof(S) * fl.n * n_, cudaMemcpyDeviceToHost, stream_), "download");
    check(cudaStreamSynchronize(stream_), "download");
    return host_;
  }
  std::vector<S> fetch_all() {
    FieldList fl{};
    for (int f = 0; f < Lay::N; ++f) fl.f[fl.n++] = f;
    const S* h = fetch(fl);
    return std::vector<S>(h, h + static_cast<size_t>(Lay::N) * n_);
  }

  StepParams<D, S, Model> sp_;
  long n_;
  CudaOptions opt_;
  int key_bits_ = 32;
  int stage_ = 0;
  double damping_ = 0, flip_ = 0;
  double t_ = 0;  // time after the last span: step() goes on from it
  long since_sort_ = 0;
  cudaStream_t stream_ = nullptr;
  S* part_ = nullptr;              // particle fields (ParticleLayout), slots in sorted order
  S* alt_ = nullptr;               // gather target of a sort; staging of downloads
  S* grid_ = nullptr;
  std::uint32_t* status_ = nullptr;
  std::uint32_t* info_ = nullptr;  // per-slot update record (not reduced on the GPU yet)
  std::uint32_t* ids_ = nullptr;   // original index of each slot
  std::uint32_t* ids_alt_ = nullptr;
  std::uint32_t* inv_ = nullptr;   // slot of each original index
  std::uint32_t* deferred_ = nullptr;  // slots whose plastic return the split G2P deferred
  unsigned* n_deferred_ = nullptr;     // their count (zeroed by the second pass)
  double fused_waves_ = 0;             // n / (threads of the fused G2P kernel resident at once)
  long* keys_ = nullptr;           // bin of each particle (volumetric averaging)
  S* bins_ = nullptr;              // per-bin V and V tr L (volumetric averaging)
  std::uint32_t* sort_buf_[4] = {nullptr, nullptr, nullptr, nullptr};  // keys in/out, slots in/out
  unsigned char* sort_tmp_ = nullptr;
  size_t sort_tmp_bytes_ = 0;
  SpanControl* ctl_ = nullptr;
  SpanControl* ctl_in_ = nullptr;  // pinned
  SpanControl* ctl_out_ = nullptr; // pinned
  S* host_ = nullptr;              // pinned download staging
  long* sub_ids_ = nullptr;
  S* sub_out_ = nullptr;
  long sub_cap_ = 0;
  std::vector<std::uint8_t*> masks_;
  std::vector<bool> contacts_;  // per stage: the grid kernel with contact_node
  std::map<long, cudaGraphExec_t> graphs_;
  cudaEvent_t ev_[kNumEvents];
  PhaseTimes times_;
};

}  // namespace

template <int D, class S, class Model, class Shape, bool kB>
std::unique_ptr<Runner> make_cuda_runner_t(const SceneSetup& su, const CudaOptions& opt) {
  return std::make_unique<CudaRunner<D, S, Model, Shape, kB>>(su, opt);
}

}  // namespace granflow::mpm

// Explicit instantiations of one model and shape (2D; 3D with GRANFLOW_MPM_CUDA_3D).
// GF_MPM_CUDA_INSTANTIATE: fp64 (double storage), with and without boundary code.
// GF_MPM_CUDA_INSTANTIATE_FLOAT: float storage (MODEL<double>: mixed, MODEL<float>: fp32), with
// boundary code only (runner_common.hpp, dispatch).
#define GF_MPM_CUDA_INSTANTIATE_ONE(D, S, MODEL, SHAPE, KB)                                                  \
  template std::unique_ptr<granflow::mpm::Runner> granflow::mpm::make_cuda_runner_t<D, S, MODEL, SHAPE, KB>( \
      const granflow::mpm::SceneSetup&, const granflow::mpm::CudaOptions&);
#define GF_MPM_CUDA_INSTANTIATE_D(D, MODEL, SHAPE)                 \
  GF_MPM_CUDA_INSTANTIATE_ONE(D, double, MODEL, SHAPE, false) \
  GF_MPM_CUDA_INSTANTIATE_ONE(D, double, MODEL, SHAPE, true)
#ifdef GRANFLOW_MPM_CUDA_3D
#define GF_MPM_CUDA_INSTANTIATE(MODEL, SHAPE) \
  GF_MPM_CUDA_INSTANTIATE_D(2, MODEL, SHAPE)  \
  GF_MPM_CUDA_INSTANTIATE_D(3, MODEL, SHAPE)
#define GF_MPM_CUDA_INSTANTIATE_FLOAT(MODEL, SHAPE)                \
  GF_MPM_CUDA_INSTANTIATE_ONE(2, float, MODEL, SHAPE, true) \
  GF_MPM_CUDA_INSTANTIATE_ONE(3, float, MODEL, SHAPE, true)
#else
#define GF_MPM_CUDA_INSTANTIATE(MODEL, SHAPE) GF_MPM_CUDA_INSTANTIATE_D(2, MODEL, SHAPE)
#define GF_MPM_CUDA_INSTANTIATE_FLOAT(MODEL, SHAPE) GF_MPM_CUDA_INSTANTIATE_ONE(2, float, MODEL, SHAPE, true)
#endif
