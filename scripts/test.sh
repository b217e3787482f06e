#!/usr/bin/env bash
# Set-up to result: install every package, build everything, and run every test with ctest.
# The options are set explicitly: a build/ that scripts/quickstart.sh configured (tests and CUDA
# off, no pybind11 then) is switched to the full build; CMake would keep the cached values.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install_deps.sh --tests
# Without a GPU the CUDA kernels are compiled to PTX only (no ptxas, no run here): the front end
# and NVVM still check every instantiation, in three quarters of the time; ptxas and its
# register tables: scripts/ptxas_report.sh (docs/reliability_ci.md).
cuda_arch=90
nvidia-smi -L >/dev/null 2>&1 || cuda_arch=90-virtual
scripts/build.sh -DGRANFLOW_TESTS=ON -DGRANFLOW_CUDA=ON -DGRANFLOW_PYTHON=ON -DGRANFLOW_MPI=ON -DGRANFLOW_GDAL=ON \
                 -DCMAKE_CUDA_ARCHITECTURES=$cuda_arch
# ctest -j runs OpenMP tests side by side on few cores: threads spinning at barriers would wait on
# each other's time slices (docs/reliability_ci.md)
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
cd build
ctest --output-on-failure -j"$(nproc 2>/dev/null || echo 2)"
