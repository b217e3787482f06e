#!/usr/bin/env bash
# Set-up to result: install every package, build everything, and run every test with ctest.
# The options are set explicitly: a build/ that scripts/quickstart.sh configured (tests and CUDA
# off, no pybind11 then) is switched to the full build; CMake would keep the cached values.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install_deps.sh --tests
scripts/build.sh -DGRANFLOW_TESTS=ON -DGRANFLOW_CUDA=ON -DGRANFLOW_PYTHON=ON -DGRANFLOW_MPI=ON -DGRANFLOW_GDAL=ON
# ctest -j runs OpenMP tests side by side on few cores: threads spinning at barriers would wait on
# each other's time slices (docs/reliability_ci.md)
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
cd build
ctest --output-on-failure -j"$(nproc 2>/dev/null || echo 2)"
