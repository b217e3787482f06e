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
  if constexpr (kMembers) {
    // entry j is particle subset[j] of member subset[j] / P: one "member" per entry
    std::vector<MV> vals(m);
    for (long j = 0; j < m; ++j) vals[j] = values_[sp_.members.of_particle(subset[j])];
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
