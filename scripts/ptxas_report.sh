#!/usr/bin/env bash
# Register use, spills and stack of the MPM CUDA kernels (ptxas -v, sm_${CUDA_ARCH:-90}):
# compiles the four kernel files of the CUDA backend and prints scripts/ptxas_report.py's table.
# Eigen from .deps/include (GPU machine) or /usr/include/eigen3.
set -euo pipefail
cd "$(dirname "$0")/.."
NVCC=${NVCC:-$(command -v nvcc || echo /usr/local/cuda/bin/nvcc)}
EIGEN=$([ -d .deps/include/Eigen ] && echo "$PWD/.deps/include" || echo /usr/include/eigen3)
log=${1:-/tmp/granflow_ptxas.log}
: > "$log"
for f in mpm/src/cuda/kernels/cuda_kernels_*.cu; do
  "$NVCC" -O3 -DNDEBUG -std=c++17 --generate-code=arch=compute_${CUDA_ARCH:-90},code=sm_${CUDA_ARCH:-90} \
    --expt-relaxed-constexpr -diag-suppress 20012,20014,20015 -Impm/include -Impm/src -Iconstitutive/include -isystem "$EIGEN" \
    -Xptxas -v -c "$f" -o /dev/null >> "$log" 2>&1 &
done
wait
python3 scripts/ptxas_report.py "$log"
