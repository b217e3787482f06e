// CUDA backend: what leaves the device. Frames (light: positions, velocities and temperature of
// every particle, full records of a subset; or every field), downloads of the particle state,
// all in the particles' original order.
#pragma once

#include <cuda_runtime.h>

#include <algorithm>
#include <stdexcept>
#include <vector>

#include "cuda_runner_class.cuh"

namespace granflow::mpm {
namespace {

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

// Fields of a light frame: x, v and sqrt(T) of every particle.
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline FieldList CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::light_fields() {
  FieldList fl{};
  for (int d = 0; d < D; ++d) {
    fl.f[fl.n++] = Lay::X + d;
    fl.f[fl.n++] = Lay::V + d;
  }
  if constexpr (kColl) fl.f[fl.n++] = Lay::SQT;
  return fl;
}

// A light frame from the host copy h of light_fields() in the original order.
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::fill_light(const S* h, Frame& out) const {
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
}

// The subset's records from their fields (small: Lay::N x m, subset order), evaluated by the
// host code of make_frame.
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::fill_subset(const std::vector<S>& small,
                                                                            const std::vector<long>& subset,
                                                                            Frame& out) const {
  const long m = static_cast<long>(subset.size());
  std::vector<long> all(m);
  for (long j = 0; j < m; ++j) all[j] = j;
  Frame tmp;
  if constexpr (kMembers) {
    // entry j is particle subset[j] of member subset[j] / P: one "member" per entry
    std::vector<MV> vals(m);
    const Members<typename Model::Params, S> hm = host_members();
    for (long j = 0; j < m; ++j) vals[j] = values_[hm.value_index(hm.of_particle(subset[j]), subset[j])];
    Members<typename Model::Params, S> per_entry;
    per_entry.count = static_cast<int>(m);
    per_entry.particles = 1;
    per_entry.values = vals.data();
    detail::make_frame<D, S, Model>(small, m, sp_.mp, tmp, false, all, per_entry);
  } else {
    detail::make_frame<D, S, Model>(small, m, sp_.mp, tmp, false, all);
  }
  out.subset = std::move(tmp.subset);
}

template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::frame(Frame& out, bool diagnostics,
                                                                      const std::vector<long>& subset) {
  if (diagnostics) {
    std::vector<S> host = fetch_all();
    if constexpr (kMembers)
      detail::make_frame<D, S, Model>(host, n_, sp_.mp, out, diagnostics, subset, host_members());
    else
      detail::make_frame<D, S, Model>(host, n_, sp_.mp, out, diagnostics, subset);
    return;
  }
  // light frame: x, v and sqrt(T) of every particle, full records of the subset only
  fill_light(fetch(light_fields()), out);
  if (subset.empty()) return;
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
  fill_subset(small, subset, out);
}

// snapshot(): the gather kernels run on the step stream behind the queued steps, into buffers
// of their own; the copy to pinned memory runs on a second stream, overlapping the next span
// (64 members of the 5 mm column sampled every 1 ms: the synchronous frame and measures cost
// 9.6 ms a sample against 6 ms of steps on an H100, docs/benchmarks.md).
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::snapshot(const std::vector<long>& subset) {
  if (snap_pending_) throw std::logic_error("snapshot: the previous snapshot was not collected");
  const FieldList fl = light_fields();
  if (!snap_dev_) {
    snap_dev_ = device_alloc<S>(static_cast<size_t>(fl.n) * n_);
    check(cudaMallocHost(&snap_host_, sizeof(S) * fl.n * n_), "cudaMallocHost");
    check(cudaStreamCreateWithFlags(&copy_stream_, cudaStreamNonBlocking), "cudaStreamCreate");
    check(cudaEventCreateWithFlags(&snap_ready_, cudaEventDisableTiming), "cudaEventCreate");
    check(cudaEventCreateWithFlags(&snap_done_, cudaEventDisableTiming), "cudaEventCreate");
  }
  const long m = static_cast<long>(subset.size());
  if (subset != snap_subset_) {
    for (long i : subset)
      if (i < 0 || i >= n_) throw std::runtime_error("snapshot: particle index out of range");
    cudaFree(snap_sub_ids_);
    cudaFree(snap_sub_dev_);
    if (snap_sub_host_) cudaFreeHost(snap_sub_host_);
    snap_sub_ids_ = nullptr;
    snap_sub_dev_ = nullptr;
    snap_sub_host_ = nullptr;
    if (m > 0) {
      snap_sub_ids_ = device_alloc<long>(m);
      snap_sub_dev_ = device_alloc<S>(static_cast<size_t>(Lay::N) * m);
      check(cudaMallocHost(&snap_sub_host_, sizeof(S) * Lay::N * m), "cudaMallocHost");
      check(cudaMemcpy(snap_sub_ids_, subset.data(), m * sizeof(long), cudaMemcpyHostToDevice), "snapshot subset");
    }
    snap_subset_ = subset;
  }
  unpermute_kernel<S><<<blocks_for(n_, kAuxBlock), kAuxBlock, 0, stream_>>>(part_view(), ids_, fl, snap_dev_);
  if (m > 0)
    subset_kernel<S><<<blocks_for(m, kAuxBlock), kAuxBlock, 0, stream_>>>(part_view(), inv_, snap_sub_ids_, m,
                                                                          Lay::N, snap_sub_dev_);
  check(cudaEventRecord(snap_ready_, stream_), "snapshot");
  check(cudaStreamWaitEvent(copy_stream_, snap_ready_, 0), "snapshot");
  check(cudaMemcpyAsync(snap_host_, snap_dev_, sizeof(S) * fl.n * n_, cudaMemcpyDeviceToHost, copy_stream_),
        "snapshot");
  if (m > 0)
    check(cudaMemcpyAsync(snap_sub_host_, snap_sub_dev_, sizeof(S) * Lay::N * m, cudaMemcpyDeviceToHost,
                          copy_stream_),
          "snapshot");
  check(cudaEventRecord(snap_done_, copy_stream_), "snapshot");
  snap_pending_ = true;
}

template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::collect(Frame& out) {
  if (!snap_pending_) throw std::logic_error("collect: no snapshot pending");
  check(cudaSetDevice(device_), "cudaSetDevice");  // collect may run on a thread of its own
  check(cudaEventSynchronize(snap_done_), "snapshot");
  snap_pending_ = false;
  fill_light(snap_host_, out);
  const long m = static_cast<long>(snap_subset_.size());
  if (m == 0) return;
  fill_subset(std::vector<S>(snap_sub_host_, snap_sub_host_ + static_cast<size_t>(Lay::N) * m), snap_subset_, out);
}

// The listed fields of every particle in the original order, in pinned host memory.
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline const S* CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::fetch(const FieldList& fl) {
  if (!host_) check(cudaMallocHost(&host_, sizeof(S) * Lay::N * n_), "cudaMallocHost");
  unpermute_kernel<S><<<blocks_for(n_, kAuxBlock), kAuxBlock, 0, stream_>>>(part_view(), ids_, fl, alt_);
  check(cudaMemcpyAsync(host_, alt_, sizeof(S) * fl.n * n_, cudaMemcpyDeviceToHost, stream_), "download");
  check(cudaStreamSynchronize(stream_), "download");
  return host_;
}

template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline std::vector<S> CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::fetch_all() {
  FieldList fl{};
  for (int f = 0; f < Lay::N; ++f) fl.f[fl.n++] = f;
  const S* h = fetch(fl);
  return std::vector<S>(h, h + static_cast<size_t>(Lay::N) * n_);
}

}  // namespace
}  // namespace granflow::mpm
