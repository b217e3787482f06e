// CUDA kernels of 3D scenes of several materials (kMembers, with boundary code, fp64), one
// model, both shapes (see cuda_runner_impl.cuh); built only with GRANFLOW_MPM_CUDA_3D.
#include "cuda/cuda_runner_impl.cuh"

GF_MPM_CUDA_INSTANTIATE_MATERIALS_3D(double, granflow::FrictionalModel<double>, granflow::mpm::LinearShape)
GF_MPM_CUDA_INSTANTIATE_MATERIALS_3D(double, granflow::FrictionalModel<double>, granflow::mpm::QuadraticShape)
