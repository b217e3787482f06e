#!/usr/bin/env bash
# Set-up to result: install every package, build everything, and run every test with ctest.
# The options are set explicitly: a build/ that scripts/quickstart.sh configured (tests and CUDA
# off, no pybind11 then) is switched to the full build; CMake would keep the cached values.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install_deps.sh --tests
# Without a GPU nothing runs the CUDA kernels here: they are compiled only to check them, to PTX
# (no ptxas), without optimisation (NVVM and the host side at -O0) and in two batches of kernel
# files: the front end still checks every instantiation, in a fifth of the time; ptxas and its
# register tables: scripts/ptxas_report.sh (docs/reliability_ci.md).
cuda_arch=90 cuda_flags="-O3 -DNDEBUG" cuda_batches=OFF
nvidia-smi -L >/dev/null 2>&1 || { cuda_arch=90-virtual; cuda_flags="-O0 -Xcicc -O0 -DNDEBUG"; cuda_batches=ON; }
# Unity builds (CMAKE_UNITY_BUILD): the sources of a target compile in batches, so the headers
# they share (Eigen, CLI11, GoogleTest) are compiled once per batch (docs/reliability_ci.md).
source scripts/generator.sh  # fast_linker: lld where installed
scripts/build.sh $(fast_linker) -DGRANFLOW_TESTS=ON -DGRANFLOW_CUDA=ON -DGRANFLOW_PYTHON=ON -DGRANFLOW_MPI=ON -DGRANFLOW_GDAL=ON \
                 -DCMAKE_CUDA_ARCHITECTURES=$cuda_arch -DCMAKE_CUDA_FLAGS_RELEASE="$cuda_flags" \
                 -DGRANFLOW_CUDA_KERNEL_BATCHES=$cuda_batches -DCMAKE_UNITY_BUILD=ON
# ctest -j runs OpenMP tests side by side on few cores: threads spinning at barriers would wait on
# each other's time slices (docs/reliability_ci.md)
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
cd build
ctest --output-on-failure -j"$(nproc 2>/dev/null || echo 2)"
