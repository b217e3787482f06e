#!/usr/bin/env bash
# Builds granflow and its tests with AddressSanitizer + UndefinedBehaviorSanitizer
# (GRANFLOW_SANITIZE=ON, CUDA off; no Python module, no Fortran driver) in build-asan/ and runs
# every test with ctest but the long ones that tests/plain_only.txt names with the shorter test
# that runs their code here (docs/reliability_ci.md).
# Any sanitizer report fails the run (-fno-sanitize-recover=all; halt_on_error).
#   scripts/sanitize.sh            # configure, build, test
#   JOBS=4 scripts/sanitize.sh     # more build/test jobs
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=${JOBS:-$(nproc 2>/dev/null || echo 2)}
start=$(date +%s)
# -O1 -g1: AddressSanitizer's recommended level, and line tables only, enough for the reports'
# file:line stacks. Against -O2 -g: about half the compile time, the tests about 10 % slower
# (docs/reliability_ci.md).
source scripts/generator.sh
cmake -S . -B build-asan $(cmake_generator build-asan) $(fast_linker) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
      -DGRANFLOW_SANITIZE=ON -DGRANFLOW_CUDA=OFF -DGRANFLOW_TESTS=ON -DCMAKE_UNITY_BUILD=ON >/dev/null
cmake --build build-asan -j"$jobs"
built=$(date +%s)
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:detect_stack_use_after_return=1:check_initialization_order=1:strict_init_order=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
# Open MPI's own allocations at exit (the Mpi.* tests run granflow under mpirun): not granflow's leaks
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$PWD/scripts/lsan_openmpi.supp:print_suppressions=0}
# ctest -j runs OpenMP tests side by side on few cores: threads spinning at barriers would wait on
# each other's time slices (docs/reliability_ci.md)
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
skip=$(sed -e 's/#.*//' -e 's/[[:space:]]//g' -e '/^$/d' tests/plain_only.txt | paste -sd'|' -)
cd build-asan
ctest --output-on-failure -j"$jobs" --timeout 1500 -E "^($skip)\$"
end=$(date +%s)
echo "sanitize: build $((built - start)) s, tests $((end - built)) s, total $((end - start)) s"
