#!/usr/bin/env bash
# GPU session of the performance work (issue 7; docs/mpm.md "GPU step", docs/benchmarks.md):
#   1. build (scripts/gpu_build.sh)
#   2. GPU against CPU twin: OMP_NUM_THREADS=8 build-gpu/mpm_cuda_check --short (0.5 %, original order)
#   3. 1 mm column benchmark matrix: baseline-like loop, spans, graphs, sorting, P2G variants, G2P variants
#   4. the full 1 mm column run (granflow-mpm column --backend cuda --out /tmp/x), timed
#   5. the 5 mm flume benchmark
#   6. if time is left: the first 0.35 s of the column, baseline-like settings against the defaults
# Run on the GPU machine from the repository root with $OUT set and .deps/include present.
# Compact figures on stdout, full logs in $OUT; about 5 minutes (items are skipped past 8.5).
set -o pipefail
: "${OUT:?set OUT to a folder for the logs}"
T0=$SECONDS
left() { echo $((510 - (SECONDS - T0))); }
B=./build-gpu
M=$B/granflow-mpm

echo "== build"
(time timeout 330 scripts/gpu_build.sh) > "$OUT/build.log" 2>&1
tail -3 "$OUT/build.log"
if [ ! -x $M ] || [ ! -x $B/mpm_cuda_check ]; then
  echo "build failed:"; grep -E "error|Error" "$OUT/build.log" | head -20; exit 1
fi
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm --format=csv,noheader 2>/dev/null | head -1

echo "== GPU vs CPU twin: mpm_cuda_check --short (run-out/height within 0.5 %, points in original order)"
OMP_NUM_THREADS=8 timeout 170 $B/mpm_cuda_check --short > "$OUT/cuda_check.log" 2>&1
echo "exit code $? (0: all OK)" | tee -a "$OUT/cuda_check.log"
sed -E 's/ cpu run-out .* rel\. diff/ rel. diff/; s/^(falling block: [^\n]*(OK|FAIL)).*/\1/' "$OUT/cuda_check.log" |
  grep -E "OK|FAIL"

# bench LABEL ARGS...: one line of figures from granflow-mpm ARGS --bench
bench() {
  local label=$1; shift
  local log="$OUT/bench_$(printf %s "$label" | tr -c 'a-zA-Z0-9-' _).log"
  timeout 90 $M "$@" > "$log" 2>&1 || echo "  ($label: exit code $?, see $log)"
  awk -v l="$label" '
    /^time per step/ {t = $4}
    /device time per step/ {d = $(NF - 1)}
    /^  P2G:/ {p = $2}
    /^  grid update:/ {g = $3}
    /^  G2P \+ constitutive:/ {c = $4}
    /^  sort \(amortised\)/ {s = $(NF - 1)}
    END {printf "%-46s %8s us/step (device %6s) | timed split: P2G %6s grid %5s G2P %6s sort %5s\n", l, t, d, p, g, c, s}' "$log"
}
BASE="--loop step --graphs off --sort 0 --p2g atomic"
COL="column --backend cuda --bench 300 --warmup 20"

echo "== 1 mm column benchmark (80,000 points, 300 steps of the consolidation after 20; us per step)"
bench "baseline-like (step loop, no graphs/sort, atomic)" $COL $BASE
bench "spans, no graphs, no sort, atomic P2G" $COL --graphs off --sort 0 --p2g atomic
bench "spans + graphs, no sort, atomic P2G" $COL --sort 0 --p2g atomic
bench "spans + graphs + sort 32, atomic P2G" $COL --p2g atomic
bench "spans + graphs + sort 32, warp P2G" $COL --p2g warp
bench "default: spans + graphs + sort 32 + tile P2G" $COL
bench "default, sort every 8" $COL --sort 8
bench "default, no graphs" $COL --graphs off
bench "default, G2P <= 168 registers" $COL --g2p-regcap on
bench "default, G2P block 64" $COL --g2p-block 64
bench "default, G2P block 256" $COL --g2p-block 256
bench "default, frictional only" $COL --model frictional
grep -E "CUDA options|registers" "$OUT/bench_default__spans___graphs___sort_32___tile_P2G.log"

echo "== full 1 mm column (1.1e5 steps, defaults): granflow-mpm column --backend cuda --out /tmp/x"
rm -rf /tmp/x
(time timeout 240 $M column --backend cuda --out /tmp/x) > "$OUT/column_full.log" 2>&1
echo "exit code $?"
grep -E "^steps|^wall|^final|device time per step|after stage 1|t_flow 1.00|^real|stopped" "$OUT/column_full.log"
for f in runout.csv tracked.csv profile_final.csv; do cp /tmp/x/$f "$OUT/column_full_$f" 2>/dev/null; done

echo "== 5 mm flume benchmark (24,000 points, 283,386 nodes)"
FL="flume --backend cuda --bench 300 --warmup 20"
bench "flume baseline-like" $FL $BASE
bench "flume spans + graphs, no sort, atomic P2G" $FL --sort 0 --p2g atomic
bench "flume default" $FL

if [ "$(left)" -gt 120 ]; then
  echo "== first 0.35 s of the 1 mm column (35,000 steps): baseline-like settings against the defaults"
  for cfg in "baseline-like|--span 1 --graphs off --sort 0 --p2g atomic" "defaults|"; do
    label=${cfg%%|*}; args=${cfg#*|}
    [ "$(left)" -gt 60 ] || { echo "  $label: skipped (time)"; continue; }
    (time timeout $(($(left) - 10)) $M column --backend cuda --stop-after 0.35 $args) > "$OUT/column_035_${label}.log" 2>&1
    echo "  $label (exit code $?): $(grep -E '^wall' "$OUT/column_035_${label}.log") $(grep -E 'device time per step' "$OUT/column_035_${label}.log" | cut -d';' -f1)"
  done
fi
echo "total $((SECONDS - T0)) s"
