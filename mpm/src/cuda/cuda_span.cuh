// CUDA backend: spans, many steps without a host round-trip. Step size, time, failure flag and
// step count live on the device (SpanControl); every kernel reads `active` at its start and
// returns at once after the span ended or failed; the last block of each step's final kernel
// records the step and plans the next one (finish_step: adaptive dt from a device
// min-reduction, landing on t_land by span.hpp's rule). One synchronisation at the end of a span.
// The steps are queued one by one, or replayed from CUDA graphs of 1, 2, 4, ... graph_steps
// steps captured once per stage; dt, flip and damping are read from SpanControl, so they need
// no re-capture.
#pragma once

#include <cuda_runtime.h>

#include <algorithm>
#include <cstring>
#include <limits>

#include "cuda_runner_class.cuh"

namespace granflow::mpm {
namespace {

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
  long long shortened;     // steps planned below dt_max by the stable limit (SpanResult)
  double dt_min;           // the smallest of those
  unsigned int blocks_done;
  // Ensembles: per member, pack_bad of its first bad particle since the last
  // retire_failed_members (kNoBadParticle: none); null for single runs. Last, so that the
  // fields above keep their offsets.
  unsigned long long* member_bad;
};

// A bad particle of member k: the span's first (which stops the span after this step) and, for
// ensembles, the member's first (retire_failed_members).
template <bool kMembers>
__device__ __forceinline__ void report_bad(SpanControl* ctl, int k, std::uint32_t id, std::uint32_t st) {
  const unsigned long long b = pack_bad(id, st);
  atomicMin(&ctl->bad, b);
  if constexpr (kMembers) atomicMin(&ctl->member_bad[k], b);
}

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
    if (c.adaptive) {
      c.dt = span_next_dt(dt_limit_value(lb), c.dt_max);
      span_count_shortened(c.dt, c.dt_max, c.shortened, c.dt_min);
    }
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

// ---- the runner's spans ------------------------------------------------------------------

// A span of one step of size dt from t; adaptive: its result's dt is the stable limit itself.
inline Span one_step_span(double t, double dt, bool adaptive) {
  Span s;
  s.max_steps = 1;
  s.t = t;
  s.dt = dt;
  s.adaptive = adaptive;
  s.dt_max = std::numeric_limits<double>::infinity();
  return s;
}

// One step is a span of one step.
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline StepResult CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::step(double dt, bool want_dt_limit) {
  const SpanResult r = advance_span(one_step_span(t_, dt, want_dt_limit));
  StepResult out = step_result(r);
  if (want_dt_limit && r.ok) out.dt_limit = r.dt;
  return out;
}

template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline SpanResult CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::advance_span(const Span& s) {
  span_start(s);
  check(cudaEventRecord(ev_[kSpan0], stream_), "event");
  if (s.timing)
    run_timed(s.max_steps);
  else
    run_queued(s.max_steps);
  check(cudaEventRecord(ev_[kSpan1], stream_), "event");
  span_fetch();
  check(cudaStreamSynchronize(stream_), "span");
  check(cudaGetLastError(), "span kernels");
  float ms = 0;
  cudaEventElapsedTime(&ms, ev_[kSpan0], ev_[kSpan1]);
  times_.device += 1e-3 * ms;
  return span_result();
}

// Queues the copy of the span's control to the device.
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::span_start(const Span& s) {
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
  c.dt_min = std::numeric_limits<double>::infinity();
  if constexpr (kMembers) c.member_bad = member_bad_;
  check(cudaMemcpyAsync(ctl_, ctl_in_, sizeof c, cudaMemcpyHostToDevice, stream_), "span start");
}

// Queues the copy of the span's control back to the host (span_result reads it after a sync).
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::span_fetch() {
  check(cudaMemcpyAsync(ctl_out_, ctl_, sizeof(SpanControl), cudaMemcpyDeviceToHost, stream_), "span end");
}

template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline SpanResult CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::span_result() {
  const SpanControl& o = *ctl_out_;
  times_.span_steps += o.steps;
  times_.deferred += static_cast<long>(o.deferred);
  t_ = o.t;
  SpanResult r;
  r.steps = o.steps;
  r.t = o.t;
  r.dt = o.dt;
  r.h_last = o.h_last;
  r.shortened = static_cast<long>(o.shortened);
  r.dt_min = o.dt_min;
  if (o.bad != kNoBadParticle) {
    r.ok = false;
    r.particle = static_cast<long>(o.bad >> 32);
    r.status = static_cast<std::uint32_t>(o.bad & 0xffffffffu);
  }
  return r;
}

// Ensembles: the members whose first bad particle the last span recorded (a failed span stops
// after the step in which they failed; the other members finished that step) are marked dead
// on the device, so every later step skips their particles, and their records are cleared.
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline std::vector<MemberFailure> CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::retire_failed_members() {
  std::vector<MemberFailure> out;
  if constexpr (kMembers) {
    const int nm = sp_.members.count;
    std::vector<unsigned long long> bad(nm);
    check(cudaMemcpyAsync(bad.data(), member_bad_, sizeof(unsigned long long) * nm, cudaMemcpyDeviceToHost,
                          stream_),
          "member failures");
    check(cudaStreamSynchronize(stream_), "member failures");
    for (int k = 0; k < nm; ++k) {
      if (bad[k] == kNoBadParticle || dead_host_[k]) continue;
      dead_host_[k] = 1;
      out.push_back({k, static_cast<long>(bad[k] >> 32), static_cast<std::uint32_t>(bad[k] & 0xffffffffu)});
    }
    if (!out.empty())
      check(cudaMemcpyAsync(dead_, dead_host_.data(), sizeof(std::uint32_t) * nm, cudaMemcpyHostToDevice, stream_),
            "retire members");
    check(cudaMemsetAsync(member_bad_, 0xff, sizeof(unsigned long long) * nm, stream_), "retire members");
    check(cudaStreamSynchronize(stream_), "retire members");
  }
  return out;
}

// Graph of `steps` steps of the current stage; the first call of a stage captures every
// chunk length (1, 2, 4, ... graph_steps) so that later spans only replay.
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline cudaGraphExec_t CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::graph_for(int steps) {
  const long key = static_cast<long>(stage_) * 4096 + steps;
  auto it = graphs_.find(key);
  if (it != graphs_.end()) return it->second;
  if (graphs_.find(static_cast<long>(stage_) * 4096 + 1) == graphs_.end())
    for (int c = 1; c <= opt_.graph_steps; c *= 2) capture(c);
  it = graphs_.find(key);
  return it != graphs_.end() ? it->second : capture(steps);
}

template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline cudaGraphExec_t CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::capture(int steps) {
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
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::run_queued(long nsteps) {
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
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::run_timed(long nsteps) {
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

}  // namespace
}  // namespace granflow::mpm
