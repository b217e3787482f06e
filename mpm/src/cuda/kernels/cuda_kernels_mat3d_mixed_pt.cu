// CUDA kernels of 3D scenes of several materials (kMembers, with boundary code) in mixed
// (float storage, fp64 update), one model, both shapes (see cuda_runner_impl.cuh); built only with
// GRANFLOW_MPM_CUDA_3D.
#include "cuda/cuda_runner_impl.cuh"

GF_MPM_CUDA_INSTANTIATE_MATERIALS_3D(float, granflow::PhaseTransitionModel<double>, granflow::mpm::LinearShape)
GF_MPM_CUDA_INSTANTIATE_MATERIALS_3D(float, granflow::PhaseTransitionModel<double>, granflow::mpm::QuadraticShape)
