// CUDA kernels of the fp32 precision (float storage, float constitutive update), one model, both
// shapes (see cuda_runner_impl.cuh).
#include "cuda/cuda_runner_impl.cuh"

GF_MPM_CUDA_INSTANTIATE_FLOAT(granflow::PhaseTransitionModel<float>, granflow::mpm::LinearShape)
GF_MPM_CUDA_INSTANTIATE_FLOAT(granflow::PhaseTransitionModel<float>, granflow::mpm::QuadraticShape)
