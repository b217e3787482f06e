// CUDA kernels of ensembles (kMembers, 2D with boundary code) in the mixed precision
// (float storage, double constitutive update), one model, both shapes (see cuda_runner_impl.cuh).
#include "cuda/cuda_runner_impl.cuh"

GF_MPM_CUDA_INSTANTIATE_ENSEMBLE(float, granflow::PhaseTransitionModel<double>, granflow::mpm::LinearShape)
GF_MPM_CUDA_INSTANTIATE_ENSEMBLE(float, granflow::PhaseTransitionModel<double>, granflow::mpm::QuadraticShape)
