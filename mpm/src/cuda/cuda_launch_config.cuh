// CUDA backend: launch configuration (block sizes, the register caps behind __launch_bounds__,
// the P2G tile size), and the helpers every part uses: error check, allocation, grid size, and
// the register/occupancy line of a kernel that CudaRunner::config reports.
#pragma once

#include <cuda_runtime.h>

#include <cstdio>
#include <stdexcept>
#include <string>

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

// Blocks of kSplitBlock threads of the split's plastic pass per SM the compiler must fit. fp32: 4
// (at most 128 registers, 16 warps/SM, 188 B of spills in the ensemble kernel): the 64-member
// 5 mm column's pass 88 instead of 99.5 us, 131.8 instead of 135.5 us per step (H200); the 1 mm
// column unchanged. fp64: no bound (about 240 registers; 128 would spill heavily).
template <class MS>
constexpr int plastic_min_blocks() { return sizeof(MS) == 4 ? 4 : 1; }

// Shared-memory tile of P2G: at most this many nodes (a block's stencil box is about 60).
template <int D>
constexpr int tile_nodes() { return D == 2 ? 512 : 384; }

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

}  // namespace
}  // namespace granflow::mpm
