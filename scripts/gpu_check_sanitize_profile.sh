#!/usr/bin/env bash
# GPU session: build, compute-sanitizer (memcheck, racecheck) on small scenes, Nsight Compute
# on the three kernels of the 1 mm column, and a partial 1 mm column run with its kernel time
# per step against its wall time per step. Run on the GPU machine with $OUT set.
set -o pipefail
(time scripts/gpu_build.sh) 2>&1 | tail -3
B=./build-gpu
CS=$(command -v compute-sanitizer || ls /usr/local/cuda*/bin/compute-sanitizer 2>/dev/null | head -1)
NCU=$(command -v ncu || ls /usr/local/cuda*/bin/ncu /opt/nvidia/nsight-compute/*/ncu 2>/dev/null | head -1)
echo "compute-sanitizer: $CS; ncu: $NCU"
mkdir -p /tmp/scn
sed 's/^\[time\]/[solver]\nvolumetric_averaging = true\n\n[time]/' mpm/scenes/column_collapse_ci.toml > /tmp/scn/column_ci_volavg.toml
for scene in mpm/scenes/column_collapse_ci.toml mpm/scenes/column_collapse_ci_frictional.toml \
             /tmp/scn/column_ci_volavg.toml mpm/scenes/flume_ci.toml; do
  for tool in memcheck racecheck; do
    echo "== $tool $scene"
    timeout 240 $CS --tool $tool --error-exitcode 9 $B/granflow mpm $scene --backend cuda --stop-after 0.11 \
      --out /tmp/san_${tool}_$(basename $scene .toml) --force --no-png --quiet 2>&1 | tail -4
    echo "exit code: $?"
  done
done 2>&1 | tee $OUT/sanitizer.log
$NCU --clock-control none --launch-skip 60 --launch-count 3 --section SpeedOfLight --section LaunchStats \
  --section Occupancy --section MemoryWorkloadAnalysis $B/granflow-mpm column --backend cuda --bench 5 --warmup 60 \
  > $OUT/ncu_column.txt 2>&1; tail -5 $OUT/ncu_column.txt
grep -E "^  [a-z_]+kernel|Duration|Compute \(SM\) Throughput|Memory Throughput|Registers Per|Achieved Occupancy|Theoretical Occupancy" $OUT/ncu_column.txt | head -40
( time $B/granflow-mpm column --backend cuda --stop-after 0.35 --out /tmp/col_part ) 2>&1 | tail -14 | tee $OUT/column_partial.log
