#!/usr/bin/env bash
# Final GPU session of the second day: the paper's scenes after the physics and return-map
# fixes (run on the GPU machine from the repository root with $OUT set).
set -uo pipefail
B=build-gpu
(time scripts/gpu_build.sh) 2>&1 | grep real
R=/tmp/gf_final; mkdir -p $R; log=$OUT/final.log
run() {  # run TIMEOUT NAME ARGS...
  local tmo=$1 name=$2; shift 2; local t0=$SECONDS
  echo "== $name: granflow-mpm $*" >>$log
  timeout $tmo $B/granflow-mpm "$@" --out $R/$name 2>&1 | tr '\r' '\n' | grep -v "steps/s  ETA" >>$log
  echo "   [$name: exit ${PIPESTATUS[0]}, $((SECONDS - t0)) s]" >>$log
}
$B/granflow-mpm column --backend cuda --bench 300 --warmup 20 >>$log 2>&1
run 90 col1_pt column --backend cuda --model pt
run 90 col1_fr column --backend cuda --model frictional
run 60 col1_pt_fp32 column --backend cuda --model pt --precision fp32
run 100 fl5_pt_dt1e-5 flume --backend cuda --model pt --dt 1e-5
run 100 fl5_fr_dt1e-5 flume --backend cuda --model frictional --dt 1e-5
run 40 fl10_pt_dt1e-5 flume --backend cuda --model pt --h 0.01 --dt 1e-5
run 40 fl20_pt_dt1e-5 flume --backend cuda --model pt --h 0.02 --dt 1e-5
(cd $R && find . -name "runout.csv" -o -name "profile_final.csv" -o -name "tracked.csv" | tar czf $OUT/final_csv.tgz -T -)
