// CUDA backend of the MPM runner (docs/mpm.md, "GPU step"). Included by the cuda_kernels_*.cu
// files (one per model and shape), which instantiate make_cuda_runner_t; cuda_runner.cu
// dispatches to them. One file per responsibility:
//   cuda_launch_config.cuh   block sizes, register caps, tile size; error check, allocation,
//                            the register/occupancy line of a kernel
//   cuda_runner_class.cuh    the CudaRunner class: members, buffers, which file defines what
//   cuda_span.cuh            spans without host round-trips (SpanControl, end of a step on the
//                            device), CUDA graphs, the queued and the timed runs
//   cuda_step.cuh            the kernels of one step (P2G, grid update, fused or split G2P), their
//                            launches and the report of their configuration
//   cuda_particle_order.cuh  sorting by cell, the original order of each slot
//   cuda_sampling.cuh        frames and downloads, in the original order
// This file: the runner's buffers (allocation, release, particle upload), make_cuda_runner_t and
// the instantiation macros.
#pragma once

#include <cuda_runtime.h>

#include <cub/device/device_radix_sort.cuh>

#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>
#include <vector>

#include <granflow/mpm/binning.hpp>

#include "cuda_launch_config.cuh"
#include "cuda_particle_order.cuh"
#include "cuda_runner_class.cuh"
#include "cuda_sampling.cuh"
#include "cuda_slabs.cuh"
#include "cuda_span.cuh"
#include "cuda_step.cuh"
#include "backend/runner_common.hpp"

namespace granflow::mpm {
namespace {

template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::CudaRunner(const SceneSetup& su, const CudaOptions& opt,
                                                                      const SlabInit* slab)
    : sp_(detail::step_params<D, S, Model>(su)),
      n_(su.particles.n),
      cap_(slab ? std::max(slab->capacity, su.particles.n) : su.particles.n),
      nn_(su.n_nodes * su.members),
      opt_(opt) {
  if (slab) {
    slab_ = true;
    slab_ids_ = *slab->ids;
  }
  if (n_ < (slab ? 0 : 1) || cap_ < 1 || cap_ >= (1L << 31))
    throw std::runtime_error("CUDA backend: particle count out of range");
  if (kMembers != detail::uses_members(su)) throw std::logic_error("CUDA backend: ensemble instantiation mismatch");
  if (opt_.graph_steps < 1) opt_.graph_steps = 1;
  while (opt_.graph_steps & (opt_.graph_steps - 1)) opt_.graph_steps &= opt_.graph_steps - 1;  // power of two
  if (opt_.g2p_reg_cap && opt_.g2p_block > 128) opt_.g2p_block = 128;
  if (opt_.g2p_block < 32 || opt_.g2p_block > 256 || opt_.g2p_block % 32) opt_.g2p_block = 128;
  if constexpr (kMembers) {
    // 64-bit member-major keys (cuda_particle_order.cuh) below members * sort_key_bound
    if (opt_.p2g == CudaOptions::P2G::Tile) opt_.p2g = CudaOptions::P2G::Warp;  // no tile mode (p2g_kernel)
    if (su.particles.n % su.members != 0 || sp_.members.particles * su.members != n_)
      throw std::runtime_error("CUDA backend: the members' particle counts differ");
    const std::uint64_t bound = sort_key_bound<D>(sp_.grid.nodes);
    if (bound > ~std::uint64_t(0) / static_cast<std::uint64_t>(su.members)) {
      opt_.sort_every = 0;
    } else {
      const std::uint64_t all = bound * static_cast<std::uint64_t>(su.members);
      key_bits_ = 1;
      while (key_bits_ < 64 && (std::uint64_t(1) << key_bits_) < all) ++key_bits_;
    }
  } else {
    if (sort_key_bound<D>(sp_.grid.nodes) > (1ull << 32)) opt_.sort_every = 0;  // keys are 32 bits
    key_bits_ = 1;
    while (key_bits_ < 32 && (1ull << key_bits_) < sort_key_bound<D>(sp_.grid.nodes)) ++key_bits_;
  }

  check(cudaGetDevice(&device_), "cudaGetDevice");
  check(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking), "cudaStreamCreate");
  const size_t nf = static_cast<size_t>(Lay::N) * cap_;
  const long nn = nn_;  // of all members
  part_ = device_alloc<S>(nf);
  alt_ = device_alloc<S>(nf);
  grid_ = device_alloc<S>(static_cast<size_t>(G::N) * nn);
  if constexpr (kKeepMass) g2p_mass_ = device_alloc<S>(static_cast<size_t>(nn));
  status_ = device_alloc<std::uint32_t>(cap_);
  info_ = device_alloc<std::uint32_t>(cap_);
  if (opt_.update_stats) {
    stats_ = device_alloc<DeviceUpdateStats>(1);
    check(cudaMemset(stats_, 0, sizeof(DeviceUpdateStats)), "clear update stats");
  }
  ids_ = device_alloc<std::uint32_t>(cap_);
  ids_alt_ = device_alloc<std::uint32_t>(cap_);
  inv_ = device_alloc<std::uint32_t>(cap_);
  if (!sp_.vol_avg && use_split()) {
    deferred_ = device_alloc<std::uint32_t>(cap_);
    n_deferred_ = device_alloc<unsigned>(1);
    check(cudaMemset(n_deferred_, 0, sizeof(unsigned)), "clear deferred count");
  }
  if (sp_.vol_avg) {
    keys_ = device_alloc<long>(cap_);
    bins_ = device_alloc<S>(2 * static_cast<size_t>(nn));
  }
  if (opt_.sort_every > 0) {
    for (auto*& a : sort_keys_) a = device_alloc<SortKey>(cap_);
    for (auto*& a : sort_slots_) a = device_alloc<std::uint32_t>(cap_);
    check(cub::DeviceRadixSort::SortPairs(nullptr, sort_tmp_bytes_, sort_keys_[0], sort_keys_[1], sort_slots_[0],
                                          sort_slots_[1], static_cast<int>(cap_), 0, key_bits_, stream_),
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
  if constexpr (kTerrain) {
    if (!su.terrain.empty()) {
      n_terrain_ = static_cast<long>(su.terrain.size());
      terrain_mu_ = su.terrain_mu;
      terrain_ = device_alloc<TerrainNode>(su.terrain.size());
      check(cudaMemcpy(terrain_, su.terrain.data(), sizeof(TerrainNode) * su.terrain.size(), cudaMemcpyHostToDevice),
            "upload terrain nodes");
    }
  }
  if constexpr (kBoundary) {
    if (!su.obstacle_nodes.empty()) {
      n_obstacle_ = static_cast<long>(su.obstacle_nodes.size());
      obstacle_ = device_alloc<ObstacleNode>(n_obstacle_);
      check(cudaMemcpy(obstacle_, su.obstacle_nodes.data(), sizeof(ObstacleNode) * n_obstacle_, cudaMemcpyHostToDevice),
            "upload obstacle nodes");
    }
    if (!su.probes.empty()) {
      n_probes_ = static_cast<long>(su.probes.size());
      n_parts_ = static_cast<int>(su.force_parts.size());
      n_boundaries_ = static_cast<int>(su.force_boundaries.size());
      probes_ = device_alloc<ForceProbe>(n_probes_);
      check(cudaMemcpy(probes_, su.probes.data(), sizeof(ForceProbe) * n_probes_, cudaMemcpyHostToDevice),
            "upload force probes");
      trial_ = device_alloc<ProbeTrial>(n_probes_);
      std::vector<PartRange> ranges;
      for (const ForcePart& p : su.force_parts)
        ranges.push_back({p.first, p.count, p.boundary, {p.moment_point[0], p.moment_point[1], p.moment_point[2]}});
      parts_ = device_alloc<PartRange>(n_parts_);
      check(cudaMemcpy(parts_, ranges.data(), sizeof(PartRange) * n_parts_, cudaMemcpyHostToDevice), "upload force parts");
      part_step_ = device_alloc<ForceSums>(n_parts_);
      force_acc_ = device_alloc<ForceSums>(n_parts_ + n_boundaries_);
      node_impulse_ = device_alloc<double>(D * n_probes_);
      BoundaryForces zero;
      zero.parts.assign(n_parts_, ForceSums{});
      zero.boundaries.assign(n_boundaries_, ForceSums{});
      zero.node_impulse.assign(static_cast<size_t>(D) * n_probes_, 0.0);
      restore_forces(zero);
    }
  }
  if constexpr (kMembers) {
    // per-member values, retired flags and first bad particles (sp_.members, SpanControl)
    const int nm = su.members;
    values_ = detail::member_values<D, S, Model>(su);
    values_dev_ = device_alloc<MV>(values_.size());  // members x materials entries
    check(cudaMemcpy(values_dev_, values_.data(), sizeof(MV) * values_.size(), cudaMemcpyHostToDevice),
          "member values");
    dead_host_.assign(nm, 0u);
    dead_ = device_alloc<std::uint32_t>(nm);
    check(cudaMemset(dead_, 0, sizeof(std::uint32_t) * nm), "member flags");
    member_bad_ = device_alloc<unsigned long long>(nm);
    check(cudaMemset(member_bad_, 0xff, sizeof(unsigned long long) * nm), "member failures");  // kNoBadParticle
    sp_.members.values = values_dev_;
    sp_.members.dead = dead_;
    if (!su.point_material.empty()) {  // uploaded in load()
      material_host_ = su.point_material;
      material_ = device_alloc<std::uint8_t>(cap_);
      material_alt_ = device_alloc<std::uint8_t>(cap_);
      sp_.members.material = material_;
    }
  }
  for (auto& e : ev_) check(cudaEventCreate(&e), "cudaEventCreate");
  preload();
  load(su.particles, slab ? static_cast<const S*>(slab->packed) : nullptr);
  set_stage(0, 0.0, su.scene.flip);
}

template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::~CudaRunner() {
  cudaStreamSynchronize(stream_);
  if (copy_stream_) cudaStreamSynchronize(copy_stream_);
  for (auto& [k, g] : graphs_) cudaGraphExecDestroy(g);
  for (void* p : {static_cast<void*>(part_), static_cast<void*>(alt_), static_cast<void*>(grid_),
                  static_cast<void*>(g2p_mass_), static_cast<void*>(status_), static_cast<void*>(info_), static_cast<void*>(ids_),
                  static_cast<void*>(ids_alt_), static_cast<void*>(inv_), static_cast<void*>(keys_),
                  static_cast<void*>(bins_), static_cast<void*>(sort_tmp_), static_cast<void*>(ctl_),
                  static_cast<void*>(sub_ids_), static_cast<void*>(sub_out_), static_cast<void*>(deferred_),
                  static_cast<void*>(n_deferred_), static_cast<void*>(values_dev_), static_cast<void*>(dead_),
                  static_cast<void*>(member_bad_), static_cast<void*>(snap_dev_), static_cast<void*>(snap_sub_ids_),
                  static_cast<void*>(snap_sub_dev_), static_cast<void*>(terrain_), static_cast<void*>(material_),
                  static_cast<void*>(material_alt_), static_cast<void*>(obstacle_), static_cast<void*>(probes_),
                  static_cast<void*>(trial_), static_cast<void*>(parts_), static_cast<void*>(part_step_),
                  static_cast<void*>(force_acc_), static_cast<void*>(node_impulse_), static_cast<void*>(stats_)})
    cudaFree(p);
  if (copy_stream_) {
    cudaStreamDestroy(copy_stream_);
    cudaEventDestroy(snap_ready_);
    cudaEventDestroy(snap_done_);
  }
  if (snap_host_) cudaFreeHost(snap_host_);
  if (snap_sub_host_) cudaFreeHost(snap_sub_host_);
  for (auto* a : sort_keys_) cudaFree(a);
  for (auto* a : sort_slots_) cudaFree(a);
  for (auto* m : masks_) cudaFree(m);
  cudaFreeHost(ctl_in_);
  cudaFreeHost(ctl_out_);
  if (host_) cudaFreeHost(host_);
  for (auto& e : ev_) cudaEventDestroy(e);
  cudaStreamDestroy(stream_);
}

// The forces since the last take (queued behind the steps; a synchronisation).
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::take_forces(BoundaryForces& out, bool keep) {
  out = {};
  if (n_probes_ == 0) return;
  out.parts.resize(n_parts_);
  out.boundaries.resize(n_boundaries_);
  out.node_impulse.resize(static_cast<size_t>(D) * n_probes_);
  check(cudaMemcpyAsync(out.parts.data(), force_acc_, sizeof(ForceSums) * n_parts_, cudaMemcpyDeviceToHost, stream_),
        "download forces");
  check(cudaMemcpyAsync(out.boundaries.data(), force_acc_ + n_parts_, sizeof(ForceSums) * n_boundaries_,
                        cudaMemcpyDeviceToHost, stream_),
        "download forces");
  check(cudaMemcpyAsync(out.node_impulse.data(), node_impulse_, sizeof(double) * out.node_impulse.size(),
                        cudaMemcpyDeviceToHost, stream_),
        "download forces");
  check(cudaStreamSynchronize(stream_), "download forces");
  if (keep) return;
  BoundaryForces zero;
  zero.parts.assign(n_parts_, ForceSums{});
  zero.boundaries.assign(n_boundaries_, ForceSums{});
  zero.node_impulse.assign(out.node_impulse.size(), 0.0);
  restore_forces(zero);
}

template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::restore_forces(const BoundaryForces& in) {
  if (n_probes_ == 0 || in.parts.size() != static_cast<size_t>(n_parts_) ||
      in.boundaries.size() != static_cast<size_t>(n_boundaries_) ||
      in.node_impulse.size() != static_cast<size_t>(D) * n_probes_)
    return;
  check(cudaMemcpy(force_acc_, in.parts.data(), sizeof(ForceSums) * n_parts_, cudaMemcpyHostToDevice), "upload forces");
  check(cudaMemcpy(force_acc_ + n_parts_, in.boundaries.data(), sizeof(ForceSums) * n_boundaries_,
                   cudaMemcpyHostToDevice),
        "upload forces");
  check(cudaMemcpy(node_impulse_, in.node_impulse.data(), sizeof(double) * in.node_impulse.size(),
                   cudaMemcpyHostToDevice),
        "upload forces");
}

// Particle state from the host (the set-up, or a checkpoint through upload()). The buffer keeps
// its address, so captured graphs stay valid; the order is the original one again, and the grid
// is cleared (a failed step may have left non-finite node
// velocities, which nodes out of reach would otherwise pass on weighted by zero). Ensembles:
// retired members stay retired.
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
inline void CudaRunner<D, S, Model, Shape, kBoundary, kMembers>::load(const HostParticles& hp, const S* packed) {
  if (hp.n != n_) throw std::runtime_error("CUDA backend: particle count differs from the set-up");
  const std::vector<S> host = packed ? std::vector<S>{} : detail::pack<D, S, kColl>(hp);
  if (n_ > 0)
    check(cudaMemcpyAsync(part_, packed ? packed : host.data(), sizeof(S) * Lay::N * n_, cudaMemcpyHostToDevice,
                          stream_),
          "upload particles");
  if (material_)
    check(cudaMemcpyAsync(material_, material_host_.data(), n_, cudaMemcpyHostToDevice, stream_), "upload materials");
  if (slab_) {  // indices in the whole scene (no inverse: a slab is sampled through cuda_slabs.cuh)
    check(cudaMemcpyAsync(ids_, slab_ids_.data(), sizeof(std::uint32_t) * n_, cudaMemcpyHostToDevice, stream_),
          "upload ids");
  } else if (n_ > 0) {
    iota_kernel<<<blocks_for(n_, kAuxBlock), kAuxBlock, 0, stream_>>>(ids_, n_);
    iota_kernel<<<blocks_for(n_, kAuxBlock), kAuxBlock, 0, stream_>>>(inv_, n_);
  }
  // the grid kernel keeps mass, momentum and force zero between steps; velocities of nodes
  // no particle reaches are weighed by zero and must only be finite
  check(cudaMemsetAsync(grid_, 0, sizeof(S) * G::N * nn_, stream_), "clear grid");
  check(cudaStreamSynchronize(stream_), "upload particles");
  since_sort_ = opt_.sort_every;  // sort before the first step
}

}  // namespace

template <int D, class S, class Model, class Shape, bool kB, bool kM>
std::unique_ptr<Runner> make_cuda_runner_t(const SceneSetup& su, const CudaOptions& opt, const SlabOptions* slabs) {
  if (slabs && slabs->slabs > 1) {
    if constexpr (kB && !kM) {
      return std::make_unique<CudaSlabRunner<D, S, Model, Shape, kB>>(su, opt, *slabs);
    } else if (su.members > 1) {
      throw std::invalid_argument("slabs: an ensemble is not split (--devices spreads its members over GPUs)");
    } else if (su.scene.material_count() > 1) {
      throw std::invalid_argument("slabs: scenes of several materials are not split yet (this one has " +
                                  std::to_string(su.scene.material_count()) + ")");
    } else {
      throw std::invalid_argument("slabs: a scene without a wall, a base or a gate is not split");
    }
  }
  return std::make_unique<CudaRunner<D, S, Model, Shape, kB, kM>>(su, opt);
}

}  // namespace granflow::mpm

// Explicit instantiations of one model and shape (2D; 3D with GRANFLOW_MPM_CUDA_3D).
// GF_MPM_CUDA_INSTANTIATE: fp64 (double storage), with and without boundary code.
// GF_MPM_CUDA_INSTANTIATE_FLOAT: float storage (MODEL<double>: mixed, MODEL<float>: fp32), with
// boundary code only (runner_common.hpp, dispatch).
// GF_MPM_CUDA_INSTANTIATE_ENSEMBLE: ensembles (kMembers), 2D with boundary code, storage S
// (cuda_kernels_ens_*.cu).
// GF_MPM_CUDA_INSTANTIATE_MATERIALS_3D: single runs of several materials in 3D (kMembers, with
// boundary code, storage S; cuda_kernels_mat3d_*.cu, compiled only with GRANFLOW_MPM_CUDA_3D).
#define GF_MPM_CUDA_INSTANTIATE_ONE_M(D, S, MODEL, SHAPE, KB, KM)                                                \
  template std::unique_ptr<granflow::mpm::Runner> granflow::mpm::make_cuda_runner_t<D, S, MODEL, SHAPE, KB, KM>( \
      const granflow::mpm::SceneSetup&, const granflow::mpm::CudaOptions&, const granflow::mpm::SlabOptions*);
#define GF_MPM_CUDA_INSTANTIATE_ONE(D, S, MODEL, SHAPE, KB) GF_MPM_CUDA_INSTANTIATE_ONE_M(D, S, MODEL, SHAPE, KB, false)
#define GF_MPM_CUDA_INSTANTIATE_ENSEMBLE(S, MODEL, SHAPE) GF_MPM_CUDA_INSTANTIATE_ONE_M(2, S, MODEL, SHAPE, true, true)
#define GF_MPM_CUDA_INSTANTIATE_MATERIALS_3D(S, MODEL, SHAPE) \
  GF_MPM_CUDA_INSTANTIATE_ONE_M(3, S, MODEL, SHAPE, true, true)
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
