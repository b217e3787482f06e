// CUDA backend: particle order. Every sort_every steps particles are reordered by the cell key
// of binning.hpp (cub radix sort, gather into a second buffer, copied back so kernel arguments
// and graphs stay valid); ids_ keeps each slot's original index (inv_ its inverse), so that
// everything leaving the backend is put back into the original order.
// Ensembles: the key of a slot of member k is k * sort_key_bound + sort_key, so every sort
// keeps member k's points in slots [k P, (k + 1) P) and the member of slot p stays p / P
// (kernels.hpp, Members); the keys are 64 bits wide there.
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

// Member-major keys of an ensemble: slot p belongs to member p / P (members_particles).
template <int D, class S, class Shape, bool kColl>
__global__ void member_sort_key_kernel(ParticleView<S> pv, GridDesc<D, S> g, long members_particles,
                                       std::uint64_t member_key_stride, std::uint64_t* keys, std::uint32_t* slots) {
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (p >= pv.n) return;
  S xi[D];
  int base[D];
  particle_base<D, S, Shape, kColl>(pv, p, g, xi, base);
  keys[p] = static_cast<std::uint64_t>(p / members_particles) * member_key_stride + sort_key<D>(base, g.nodes);
  slots[p] = static_cast<std::uint32_t>(p);
}

// Slots dst0 + i of dst get slots perm[i] of src, i < count (fields and original indices): a
// sort, and a slab's points leaving or staying (cuda_slabs.cuh).
template <class S>
__global__ void gather_kernel(ParticleView<S> src, ParticleView<S> dst, int nfields, const std::uint32_t* perm,
                              long count, long dst0, const std::uint32_t* ids_src, std::uint32_t* ids_dst) {
  const long i = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (i >= count) return;
  const long from = perm[i];
  gather_slot(src, dst, nfields, dst0 + i, from);
  ids_dst[dst0 + i] = ids_src[from];
}

// Several materials: the material index of each slot follows its point.
__global__ void gather_material_kernel(const std::uint8_t* src, std::uint8_t* dst, const std::uint32_t* perm, long n) {
  const long i = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (i < n) dst[i] = src[perm[i]];
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
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::enqueue_sort() {
  const unsigned b = blocks_for(n_, kAuxBlock);
  if constexpr (kMembers)
    member_sort_key_kernel<D, S, Shape, kColl><<<b, kAuxBlock, 0, stream_>>>(
        part_view(), sp_.grid, sp_.members.particles, sort_key_bound<D>(sp_.grid.nodes), sort_keys_[0],
        sort_slots_[0]);
  else
    sort_key_kernel<D, S, Shape, kColl><<<b, kAuxBlock, 0, stream_>>>(part_view(), sp_.grid, sort_keys_[0],
                                                                      sort_slots_[0]);
  check(cub::DeviceRadixSort::SortPairs(sort_tmp_, sort_tmp_bytes_, sort_keys_[0], sort_keys_[1], sort_slots_[0],
                                        sort_slots_[1], static_cast<int>(n_), 0, key_bits_, stream_),
        "sort");
  gather_kernel<S><<<b, kAuxBlock, 0, stream_>>>(part_view(), ParticleView<S>{alt_, n_}, Lay::N, sort_slots_[1], n_,
                                                 0, ids_, ids_alt_);
  check(cudaMemcpyAsync(part_, alt_, sizeof(S) * Lay::N * n_, cudaMemcpyDeviceToDevice, stream_), "sort copy");
  check(cudaMemcpyAsync(ids_, ids_alt_, sizeof(std::uint32_t) * n_, cudaMemcpyDeviceToDevice, stream_), "sort copy");
  if (material_) {
    gather_material_kernel<<<b, kAuxBlock, 0, stream_>>>(material_, material_alt_, sort_slots_[1], n_);
    check(cudaMemcpyAsync(material_, material_alt_, n_, cudaMemcpyDeviceToDevice, stream_), "sort copy");
  }
  if (!slab_) inverse_kernel<<<b, kAuxBlock, 0, stream_>>>(ids_, inv_, n_);
}

}  // namespace
}  // namespace granflow::mpm
