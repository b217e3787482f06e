#!/usr/bin/env bash
# Builds the GPU-only configuration (constitutive library, MPM, CUDA checks, granflow with the
# MPM and benchmark commands) on a machine that has only CMake, nvcc and a folder of copied
# headers: .deps/include with Eigen/, toml++/, CLI/ and libfccp/ (scripts/copy_deps.sh makes it).
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build-gpu}
# The 3D kernels are compiled too (column_collapse_3d.toml); GRANFLOW_MPM_CUDA_3D=OFF leaves them
# out (each cuda_kernels_*.cu then compiles in about half the time).
cmake -S . -B "$build" -DGRANFLOW_GPU_ONLY=ON -DGRANFLOW_DEPS_INCLUDE="$PWD/.deps/include" \
      -DCMAKE_CUDA_ARCHITECTURES="${CUDA_ARCH:-90}" -DCMAKE_BUILD_TYPE=Release \
      -DGRANFLOW_MPM_CUDA_3D="${GRANFLOW_MPM_CUDA_3D:-ON}" >/dev/null
cmake --build "$build" -j"$(nproc)" --target granflow granflow-mpm mpm_cuda_check constitutive_device_host
