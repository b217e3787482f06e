#!/usr/bin/env bash
# Register use, spills and stack of the MPM CUDA kernels (ptxas -v, sm_${CUDA_ARCH:-90}):
# compiles the kernel files of the CUDA backend (mpm/src/cuda/kernels/) in parallel and prints
# scripts/ptxas_report.py's table. Each file logs to its own part, joined in file order, so that
# parallel compiles cannot interleave the lines of two kernels.
# Eigen from .deps/include (GPU machine) or /usr/include/eigen3.
#   scripts/ptxas_report.sh [LOG]   (default /tmp/granflow_ptxas.log)
set -euo pipefail
cd "$(dirname "$0")/.."
NVCC=${NVCC:-$(command -v nvcc || echo /usr/local/cuda/bin/nvcc)}
EIGEN=$([ -d .deps/include/Eigen ] && echo "$PWD/.deps/include" || echo /usr/include/eigen3)
log=${1:-/tmp/granflow_ptxas.log}
parts=$(mktemp -d)
files=(mpm/src/cuda/kernels/cuda_kernels_*.cu)
for i in "${!files[@]}"; do
  "$NVCC" -O3 -DNDEBUG -std=c++17 --generate-code=arch=compute_${CUDA_ARCH:-90},code=sm_${CUDA_ARCH:-90} \
    --expt-relaxed-constexpr -diag-suppress 20012,20014,20015 -Impm/include -Impm/src -Iconstitutive/include \
    -isystem "$EIGEN" -Xptxas -v -c "${files[$i]}" -o /dev/null > "$parts/$i.log" 2>&1 &
done
wait
for i in "${!files[@]}"; do cat "$parts/$i.log"; done > "$log"
rm -rf "$parts"
python3 scripts/ptxas_report.py "$log"
