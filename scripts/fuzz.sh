#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (-fsanitize=fuzzer,address,undefined) in build-fuzz/
# and runs each for a bounded time, starting from the committed seed corpus.
#   scripts/fuzz.sh [SECONDS] [TARGET...]     # default: 60 s each; parameter_set element_test csv
# Environment:
#   FUZZ_RUNS=N     stop each target after N executions instead (SECONDS then caps the time)
#   FUZZ_WORKERS=N  parallel fuzzing processes per target (libFuzzer -fork=N), default 1
#   FUZZ_CXX        the clang++ to use (default clang++)
# New inputs go to build-fuzz/corpus/<target> (not committed); a crash leaves its input in
# build-fuzz/artifacts/<target>/ and fails the script. Execution counts: build-fuzz/fuzz_<t>.log.
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-60}
[ $# -gt 0 ] && shift
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(parameter_set element_test csv)
jobs=$(nproc 2>/dev/null || echo 2)
cmake -S . -B build-fuzz -DCMAKE_CXX_COMPILER="${FUZZ_CXX:-clang++}" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      -DGRANFLOW_FUZZ=ON -DGRANFLOW_CUDA=OFF >/dev/null
cmake --build build-fuzz -j"$jobs" --target "${targets[@]/#/fuzz_}"
status=0
for t in "${targets[@]}"; do
  mkdir -p "build-fuzz/corpus/$t" "build-fuzz/artifacts/$t"
  args=(-max_total_time="$secs" -max_len=4096 -timeout=10 -rss_limit_mb=2048 -print_final_stats=1
        -artifact_prefix="build-fuzz/artifacts/$t/" -dict="tests/fuzz/$t.dict")
  [ -n "${FUZZ_RUNS:-}" ] && args+=(-runs="$FUZZ_RUNS")
  [ "${FUZZ_WORKERS:-1}" -gt 1 ] && args+=(-fork="$FUZZ_WORKERS")
  echo "== fuzz_$t: ${secs} s"
  if ! "build-fuzz/tests/fuzz/fuzz_$t" "${args[@]}" "build-fuzz/corpus/$t" "tests/fuzz/corpus/$t" \
       >"build-fuzz/fuzz_$t.log" 2>&1; then
    status=1
    echo "fuzz_$t FAILED; see build-fuzz/fuzz_$t.log and build-fuzz/artifacts/$t/"
    grep -E "ERROR|SUMMARY|==[0-9]+==" "build-fuzz/fuzz_$t.log" | head -20 || true
  fi
  grep -E "^stat::(number_of_executed_units|average_exec_per_sec|new_units_added|peak_rss_mb)" \
       "build-fuzz/fuzz_$t.log" || tail -3 "build-fuzz/fuzz_$t.log"
done
exit $status
