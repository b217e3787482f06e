// CUDA backend: dispatch to the instantiations of cuda_runner_impl.cuh, compiled in four
// files (cuda_kernels_*.cu, one per model and shape) so that they build in parallel; the float
// storage of the mixed and fp32 precisions in four more (cuda_kernels_{mixed,fp32}_*.cu), and
// ensembles (2D with boundary code) in six, one per precision and model (cuda_kernels_ens_*.cu);
// with GRANFLOW_MPM_CUDA_3D, 3D scenes of several materials in two (cuda_kernels_mat3d_*.cu).
#include <cuda_runtime.h>

#include <memory>
#include <stdexcept>
#include <string>

#include "backend/runner_common.hpp"

namespace granflow::mpm {

template <int D, class S, class Model, class Shape, bool kB, bool kM>
std::unique_ptr<Runner> make_cuda_runner_t(const SceneSetup& su, const CudaOptions& opt, const SlabOptions* slabs);

namespace {

struct MakeCuda {
  CudaOptions opt;
  const SlabOptions* slabs = nullptr;
  template <int D, class S, class Model, class Shape, bool kB, bool kM>
  std::unique_ptr<Runner> run(const SceneSetup& su) {
#ifndef GRANFLOW_MPM_CUDA_3D
    if constexpr (D == 3) {
      throw std::runtime_error("3D CUDA kernels are not compiled: configure with -DGRANFLOW_MPM_CUDA_3D=ON");
    } else
#endif
    {
      return make_cuda_runner_t<D, S, Model, Shape, kB, kM>(su, opt, slabs);
    }
  }
};

}  // namespace

bool cuda_backend_available() {
  int n = 0;
  return cudaGetDeviceCount(&n) == cudaSuccess && n > 0;
}

std::string cuda_unavailable_reason() {
  int n = 0;
  const cudaError_t e = cudaGetDeviceCount(&n);
  if (e != cudaSuccess) return std::string("no CUDA device found (") + cudaGetErrorString(e) + ")";
  return n > 0 ? std::string() : std::string("no CUDA device found");
}

int cuda_device_count() {
  int n = 0;
  return cudaGetDeviceCount(&n) == cudaSuccess ? n : 0;
}

void cuda_select_device(int device) {
  if (cudaSetDevice(device) != cudaSuccess) throw std::runtime_error("cudaSetDevice(" + std::to_string(device) + ") failed");
}

bool cuda_memory_info(std::size_t& free, std::size_t& total) {
  return cuda_backend_available() && cudaMemGetInfo(&free, &total) == cudaSuccess;
}

std::unique_ptr<Runner> make_cuda_runner(const SceneSetup& su, const CudaOptions& options) {
  if (const std::string why = cuda_unavailable_reason(); !why.empty()) throw std::runtime_error(why + "; use --backend cpu");
  return detail::dispatch(su, MakeCuda{options});
}

std::unique_ptr<Runner> make_cuda_runner(const SceneSetup& su, const CudaOptions& options, const SlabOptions& slabs) {
  if (const std::string why = cuda_unavailable_reason(); !why.empty()) throw std::runtime_error(why + "; use --backend cpu");
  return detail::dispatch(su, MakeCuda{options, &slabs});
}

}  // namespace granflow::mpm
