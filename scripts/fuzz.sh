#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (-fsanitize=fuzzer,address,undefined) in build-fuzz/
# and runs each for a bounded time, starting from the committed seed corpus.
#   scripts/fuzz.sh [SECONDS] [TARGET...]     # default: 60 s each; csv parameter_set element_test mesh
# Environment:
#   FUZZ_RUNS=N     stop each target after N executions (SECONDS still caps the time)
#   FUZZ_WORKERS=N  parallel fuzzing processes per target (libFuzzer -fork=N), default 1
#   FUZZ_CXX        the clang++ to use (default clang++)
# csv: fuzz_csv_fast (UBSan only; libfccp's 48 MB buffer makes ASan slow) explores for SECONDS,
# then every input of its corpus is run once through fuzz_csv (ASan + UBSan).
# New inputs go to build-fuzz/corpus/<target> (not committed); a crash leaves its input in
# build-fuzz/artifacts/<target>/ and fails the script. Logs and counts: build-fuzz/fuzz_<t>.log.
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-60}
[ $# -gt 0 ] && shift
targets=("$@")
# csv first: its ASan replay makes it the longest, the other two share the second core meanwhile
[ ${#targets[@]} -eq 0 ] && targets=(csv parameter_set element_test mesh)
jobs=$(nproc 2>/dev/null || echo 2)
build=()
for t in "${targets[@]}"; do
  build+=("fuzz_$t")
  [ "$t" = csv ] && build+=(fuzz_csv_fast)
done
source scripts/generator.sh
cmake -S . -B build-fuzz $(cmake_generator build-fuzz) $(fast_linker) -DCMAKE_CXX_COMPILER="${FUZZ_CXX:-clang++}" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      -DGRANFLOW_FUZZ=ON -DGRANFLOW_CUDA=OFF >/dev/null
cmake --build build-fuzz -j"$jobs" --target "${build[@]}"
bin=build-fuzz/tests/fuzz
# fuzz_one TARGET: runs one target; its report goes to build-fuzz/fuzz_TARGET.report, and the
# file build-fuzz/fuzz_TARGET.failed marks a failure.
fuzz_one() {
  local t=$1 status=0
  rm -f "build-fuzz/fuzz_$t.failed"
  {
    mkdir -p "build-fuzz/corpus/$t" "build-fuzz/artifacts/$t"
    args=(-max_total_time="$secs" -max_len=4096 -timeout=10 -rss_limit_mb=2048 -print_final_stats=1
          -artifact_prefix="build-fuzz/artifacts/$t/" -dict="tests/fuzz/$t.dict")
    [ -n "${FUZZ_RUNS:-}" ] && args+=(-runs="$FUZZ_RUNS")
    [ "${FUZZ_WORKERS:-1}" -gt 1 ] && args+=(-fork="$FUZZ_WORKERS" -ignore_crashes=0)
    exe=$bin/fuzz_$t
    [ "$t" = csv ] && exe=$bin/fuzz_csv_fast
    echo "== $(basename "$exe"): ${secs} s"
    log=build-fuzz/fuzz_$t.log
    # mesh: leaks inside assimp's own error paths are assimp's (scripts/lsan_assimp.supp)
    local lsan=${LSAN_OPTIONS:-}
    [ "$t" = mesh ] && lsan=${LSAN_OPTIONS:-suppressions=$PWD/scripts/lsan_assimp.supp:print_suppressions=0}
    if ! LSAN_OPTIONS=$lsan "$exe" "${args[@]}" "build-fuzz/corpus/$t" "tests/fuzz/corpus/$t" >"$log" 2>&1; then
      status=1
      echo "$(basename "$exe") FAILED; see $log and build-fuzz/artifacts/$t/"
      grep -E "ERROR|SUMMARY|runtime error" "$log" | head -20 || true
      # where a leak was made: its first frames, for a log that is all CI keeps
      grep -A14 -m2 -E "^(Direct|Indirect) leak" "$log" || true
    fi
    grep -E "^stat::(number_of_executed_units|average_exec_per_sec|new_units_added|peak_rss_mb)" "$log" ||
      grep -E "^#[0-9]+" "$log" | tail -1 || true
    if [ "$t" = csv ]; then  # the whole corpus once more under ASan
      echo "== fuzz_csv (ASan): replaying the corpus"
      if ! "$bin/fuzz_csv" -runs=0 -artifact_prefix="build-fuzz/artifacts/$t/" "build-fuzz/corpus/$t" \
           "tests/fuzz/corpus/$t" >"build-fuzz/fuzz_csv_asan.log" 2>&1; then
        status=1
        echo "fuzz_csv (ASan) FAILED on a corpus input; see build-fuzz/fuzz_csv_asan.log"
        grep -E "ERROR|SUMMARY|runtime error" build-fuzz/fuzz_csv_asan.log | head -20 || true
      fi
      grep -E "INITED|DONE" build-fuzz/fuzz_csv_asan.log | tail -1 || true
    fi
  } > "build-fuzz/fuzz_$t.report" 2>&1
  [ $status -eq 0 ] || touch "build-fuzz/fuzz_$t.failed"
}
# The targets run side by side, one per core (each libFuzzer process is single-threaded), and
# their reports are printed in order.
running=0
for t in "${targets[@]}"; do
  fuzz_one "$t" &
  running=$((running + 1))
  if [ $running -ge "$jobs" ]; then wait -n || true; running=$((running - 1)); fi
done
wait
status=0
for t in "${targets[@]}"; do
  cat "build-fuzz/fuzz_$t.report"
  [ ! -e "build-fuzz/fuzz_$t.failed" ] || status=1
done
exit $status
