// CUDA kernels of one model and shape (see cuda_runner_impl.cuh).
#include "cuda/cuda_runner_impl.cuh"

GF_MPM_CUDA_INSTANTIATE(granflow::FrictionalModel<double>, granflow::mpm::LinearShape)
