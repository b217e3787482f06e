#!/usr/bin/env bash
# GPU session for the precision and scale work (docs/benchmarks.md, "Precision and 3D"): run on
# the GPU machine from the repository root with $OUT set. About 7 minutes on an H200:
#   build (scripts/gpu_build.sh, 3D kernels on)                       ~3 min
#   1 mm column benchmark, fp64 / mixed / fp32 (300 steps each)         ~20 s
#   full 1 mm column (1.1e5 steps) in fp64 / mixed / fp32               ~2-3 min (each capped at 90 s)
#   3D slab (8e6 points) benchmark, fp64 / mixed / fp32 (30 steps)      ~1 min
# Prints compact figures; full logs and the run-out series go to $OUT.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/gf_precision}
mkdir -p "$OUT"
B=build-gpu
t0=$(date +%s)
elapsed() { echo $(($(date +%s) - t0)); }
budget=${BUDGET_S:-470}  # stop starting new runs after this many seconds

echo "== build"
(time scripts/gpu_build.sh $B) >"$OUT/build.log" 2>&1 || { tail -20 "$OUT/build.log"; exit 1; }
grep -E "^real" "$OUT/build.log"

# the figures of one benchmark report (granflow-mpm --bench, granflow bench mpm)
figures() {
  awk -v p=$1 '/^time per step/{t=$4} /device time per step/{d=$(NF-1)} /^  P2G:/{a=$2} /^  grid update:/{g=$3}
       /^  G2P \+ constitutive:/{c=$4} /^  sort \(amortised\)/{s=$(NF-1)} /^particle-updates/{u=$2}
       /^set-up/{su=$2" "$7}
       END{printf "%-6s %9s %9s %8s %7s %9s %6s %10s %s\n", p, t, d, a, g, c, s, u, su}' "$2"
}
header() { printf "%-6s %9s %9s %8s %7s %9s %6s %10s %s\n" prec "us/step" "device" "P2G" "grid" "G2P+con" "sort" "updates/s" "$1"; }

echo "== 1 mm column, benchmark (granflow-mpm column --bench 300 --warmup 20), consolidation steps, us"
header ""
for p in fp64 mixed fp32; do
  timeout 60 $B/granflow-mpm column --backend cuda --precision $p --bench 300 --warmup 20 >"$OUT/bench_col_$p.log" \
    2>>"$OUT/stderr.log" || echo "$p: exit code $?"
  figures $p "$OUT/bench_col_$p.log"
done
grep -h "memory:" "$OUT/stderr.log" | sed 's/^ */  /'

echo "== 1 mm column, full run (0.1 s consolidation + 1 s collapse, 1.1e5 steps)"
printf "%-6s %10s %10s %10s %14s %s\n" prec "run-out" "height" "wall [s]" "base/rho g h" "us/step: device, wall"
for p in fp64 mixed fp32; do
  if [ "$(elapsed)" -gt "$budget" ]; then echo "$p: skipped (time budget)"; continue; fi
  timeout 90 $B/granflow-mpm column --backend cuda --precision $p --out /tmp/gf_col_$p >"$OUT/col_$p.log" \
    2>"$OUT/col_$p.err"
  rc=$?
  cp /tmp/gf_col_$p/runout.csv "$OUT/col_${p}_runout.csv" 2>/dev/null
  awk -v p=$p -v rc=$rc '/final run-out/{r=$3} /final height/{h=$3} /^wall:/{w=$2}
       /after stage 1/{b=$6; g=$12; ratio=(g>0)?b/g:0}
       /kernel time per step/{k="P2G "$6" grid "$9" G2P "$14", wall "$19}
       /device time per step \(spans\)/{k=$6", "$11}
       END{if (rc!=0) printf "%-6s stopped (rc %d): see col_%s.log\n", p, rc, p;
           else printf "%-6s %10s %10s %10s %14.3f %s\n", p, r, h, w, ratio, k}' "$OUT/col_$p.log"
  grep -h "run stopped" "$OUT/col_$p.err" | head -1
done

echo "== 3D slab, 8e6 points (granflow bench mpm mpm/scenes/column_collapse_3d.toml --steps 30 --warmup 5 --split 20), us"
header "set-up [s] (scene, runner)"
for p in fp64 mixed fp32; do
  if [ "$(elapsed)" -gt "$((budget + 60))" ]; then echo "$p: skipped (time budget)"; continue; fi
  timeout 120 $B/granflow bench mpm mpm/scenes/column_collapse_3d.toml --steps 30 --warmup 5 --split 20 \
    --backend cuda --precision $p >"$OUT/bench_3d_$p.log" 2>&1 || { echo "$p: failed"; tail -3 "$OUT/bench_3d_$p.log"; continue; }
  figures $p "$OUT/bench_3d_$p.log"
done
grep -h "memory:" "$OUT"/bench_3d_*.log
grep -h "^device" "$OUT"/bench_3d_fp64.log
echo "total $(elapsed) s"
