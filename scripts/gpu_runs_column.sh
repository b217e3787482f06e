#!/usr/bin/env bash
# GPU session: build, host/device and GPU/CPU checks, column benchmark, full 1 mm column runs.
# Run on the GPU machine from the repository root with $OUT set (the device tool does).
set -o pipefail
(time scripts/gpu_build.sh) 2>&1 | tail -3
B=./build-gpu
$B/tests/cuda/constitutive_device_host 2>&1 | tee $OUT/device_host.log | tail -4
OMP_NUM_THREADS=8 $B/mpm_cuda_check --short 2>&1 | tee $OUT/cuda_check.log | tail -6
$B/granflow-mpm column --backend cuda --bench 300 --warmup 20 2>&1 | tee $OUT/bench.log | tail -9
$B/granflow-mpm column --backend cuda --bench 300 --warmup 20 --model frictional 2>&1 | tee -a $OUT/bench.log | tail -5
us=$(grep "time per step" $OUT/bench.log | head -1 | awk '{print $4}')
est=$(python3 -c "print(int(float('$us')*1.1e5/1e6))")
echo "estimated full column run: $est s"
for m in pt frictional; do
  if [ "$est" -lt 170 ]; then
    ( time timeout 200 $B/granflow-mpm column --backend cuda --model $m --out /tmp/col_$m ) 2>&1 | tail -8
  else
    ( time timeout 200 $B/granflow-mpm column --backend cuda --model $m --out /tmp/col_$m --stop-after 0.3 ) 2>&1 | tail -8
  fi
  for f in runout.csv tracked.csv profile_final.csv; do cp /tmp/col_$m/$f $OUT/col_${m}_$f 2>/dev/null; done
done
ls /tmp/col_pt | head
