// CUDA backend: particle order. Every sort_every steps particles are reordered by the cell key
// of binning.hpp (cub radix sort, gather into a second buffer, copied back so kernel arguments
// and graphs stay valid); ids_ keeps each slot's original index (inv_ its inverse), so that
// everything leaving the backend is put back into the original order.
#pragma once

#include <cuda_runtime.h>

#include <cub/device/device_radix_sort.cuh>

#include <granflow/mpm/binning.hpp>

#include "cuda_runner_class.cuh"

namespace granflow::mpm {
namespace {

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

// Reorders the particles by cell key (binning.hpp): slot i receives slot perm[i].
template <int D, class S, class Model, class Shape, bool kBoundary>
inline void CudaRunner<D, S, Model, Shape, kBoundary>::enqueue_sort() {
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

}  // namespace
}  // namespace granflow::mpm
