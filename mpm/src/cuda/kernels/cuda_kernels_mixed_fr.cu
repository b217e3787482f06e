// CUDA kernels of the mixed precision (float storage, double constitutive update), one model, both
// shapes (see cuda_runner_impl.cuh).
#include "cuda/cuda_runner_impl.cuh"

GF_MPM_CUDA_INSTANTIATE_FLOAT(granflow::FrictionalModel<double>, granflow::mpm::LinearShape)
GF_MPM_CUDA_INSTANTIATE_FLOAT(granflow::FrictionalModel<double>, granflow::mpm::QuadraticShape)
