#!/usr/bin/env bash
# GPU session for the error-against-run-time series of issues 5 and 7 (run on the GPU machine
# from the repository root, $OUT set). Every run appends one row to $OUT/<part>.csv:
#   scene,h_mm,dt_mode,dt_max,precision,model,exit,steps,wall_s,device_us_per_step,
#   runout_0.4,runout_0.8,runout_final,height_final,t_end,extra (the run's further arguments)
# and its whole summary to $OUT/<part>.log; its CSV outputs go to $OUT/<part>.tgz.
#   scripts/gpu_runs_series.sh check    build, GPU checks, benchmarks, the 20 mm flume's step
#   scripts/gpu_runs_series.sh column   column mesh series 10/5/2.5/1 mm: fixed and CFL step,
#                                       fp64 and fp32, both models at 1 mm, linear shapes at 5 mm
#   scripts/gpu_runs_series.sh flume    flume mesh series 20/10/5 (2.5) mm: the same axes
#   scripts/gpu_runs_series.sh paperdt  the flume at the paper's dt of 1e-6 s, capped
#   scripts/gpu_runs_series.sh split    checks; benchmarks of the split G2P against the fused one
#                                       (and with the first pass at 128 registers); the 1 mm column
#                                       and 5 mm flume with the split
#   scripts/gpu_runs_series.sh 3d       the 3D slab (8e6 points) benchmark with the CUDA options
#                                       (GRANFLOW_MPM_CUDA_3D=ON for the build)
#   scripts/gpu_runs_series.sh final    checks, benchmarks, the 1 mm column and 5 mm flume again,
#                                       compute-sanitizer memcheck/racecheck of the CI scenes
#                                       (NO_SANITIZE=1: without; FINAL_EXTRA='--sort 32 ...': the
#                                       1 mm column again with those options; GRANFLOW_MPM_CUDA_3D=ON:
#                                       also the 3D slab benchmark)
# TMO (seconds) caps each run; a capped run's row has exit 124 and what it reached.
set -uo pipefail
part=${1:-check}
B=build-gpu
if [ ! -x $B/granflow-mpm ]; then
  t0=$SECONDS
  GRANFLOW_MPM_CUDA_3D=${GRANFLOW_MPM_CUDA_3D:-OFF} scripts/gpu_build.sh >/dev/null || exit 1
  echo "build: $((SECONDS - t0)) s" >>$OUT/$part.log
fi
R=/tmp/gf_series/$part
mkdir -p $R
log=$OUT/$part.log
csv=$OUT/$part.csv
[ -f $csv ] || echo "scene,h_mm,dt_mode,dt_max,precision,model,exit,steps,wall_s,device_us_per_step,runout_0.4,runout_0.8,runout_final,height_final,t_end,extra" >$csv
run() {  # run SCENE H DT MODE(fixed|cfl:X) PRECISION MODEL [extra args]
  local scene=$1 h=$2 dt=$3 mode=$4 prec=$5 model=$6
  shift 6
  local name=${scene}_${h}_${mode/:/}_${prec}_${model}${1:+_x} extra="$*"
  local args=($scene --backend ${BACKEND:-cuda} --h $h --dt $dt --precision $prec --model $model "$@")
  [ "${mode%%:*}" = cfl ] && args+=(--adaptive ${mode#cfl:})
  echo "== $name: granflow-mpm ${args[*]}" >>$log
  local t0=$SECONDS
  timeout ${TMO:-120} $B/granflow-mpm "${args[@]}" --out $R/$name >$R/$name.txt 2>&1
  local rc=$?
  tr '\r' '\n' <$R/$name.txt | grep -v "steps/s  ETA" >>$log
  echo "   [$name: exit $rc, $((SECONDS - t0)) s]" >>$log
  # a run stopped by its cap has no summary: its last progress line says how far it got
  tr '\r' '\n' <$R/$name.txt | awk -v scene=$scene -v h=$h -v mode=$mode -v dt=$dt -v prec=$prec -v model=$model -v rc=$rc \
      -v wall=$((SECONDS - t0)) -v extra="$extra" '
    /^steps:/ {steps=$2} /^wall:/ {wall=$2} /^final run-out:/ {ro=$3} /^final height:/ {ht=$3}
    /^simulated:/ {tend=$2}
    /device time per step \(spans\)/ {dev=$6}
    /t_flow 0.40 s:/ {r4=$5} /t_flow 0.80 s:/ {r8=$5} /^ *t = / {tend=$3}
    END {
      printf "%s,%g,%s,%s,%s,%s,%d,%s,%s,%s,%s,%s,%s,%s,%s,%s\n", scene, h * 1000, mode, dt, prec, model, rc,
             steps, wall, dev, r4, r8, ro, ht, tend, extra
    }' >>$csv
}
if [ "$part" = check ]; then
  nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv >>$log
  timeout 60 $B/tests/cuda/constitutive_device_host >>$log 2>&1; echo "constitutive_device_host exit $?" >>$log
  OMP_NUM_THREADS=8 timeout 150 $B/mpm_cuda_check --short >>$log 2>&1; echo "mpm_cuda_check exit $?" >>$log
  echo "== bench column 1 mm pt" >>$log
  $B/granflow-mpm column --backend cuda --bench 300 --warmup 20 >>$log 2>&1
  echo "== bench flume 5 mm pt" >>$log
  $B/granflow-mpm flume --backend cuda --bench 300 --warmup 20 >>$log 2>&1
  TMO=60 run flume 0.02 1e-5 fixed fp64 pt --stop-after 0.5
  TMO=100 run column 0.001 1e-5 fixed fp64 pt
elif [ "$part" = column ]; then
  for hd in "10 1e-4" "5 5e-5" "2.5 2.5e-5"; do
    set -- $hd
    h=$(awk -v m=$1 'BEGIN{print m/1000}')
    for prec in fp64 fp32; do
      run column $h $2 fixed $prec pt
      run column $h 1e-4 cfl:0.5 $prec pt
    done
  done
  run column 0.005 5e-5 fixed fp64 frictional
  run column 0.005 5e-5 fixed fp64 pt --shape linear
  TMO=100 run column 0.001 1e-5 fixed fp64 frictional
  TMO=100 run column 0.001 1e-5 fixed fp32 pt
  TMO=100 run column 0.001 1e-4 cfl:0.5 fp64 pt
  TMO=100 run column 0.001 1e-4 cfl:0.5 fp32 pt
elif [ "$part" = flume ]; then
  for h in 0.02 0.01 0.005; do
    for prec in fp64 fp32; do
      TMO=150 run flume $h 1e-5 fixed $prec pt
      TMO=150 run flume $h 1e-4 cfl:0.5 $prec pt
    done
  done
  TMO=150 run flume 0.005 1e-4 cfl:0.5 fp64 frictional
  TMO=150 run flume 0.005 1e-5 fixed fp64 frictional
elif [ "$part" = split ]; then
  timeout 60 $B/tests/cuda/constitutive_device_host >>$log 2>&1; echo "constitutive_device_host exit $?" >>$log
  OMP_NUM_THREADS=8 timeout 150 $B/mpm_cuda_check --short >>$log 2>&1; echo "mpm_cuda_check exit $?" >>$log
  for sc in column flume; do
    for opts in "--g2p-split off" "--g2p-split on" "--g2p-split on --g2p-regcap on"; do
      echo "== bench $sc pt $opts" >>$log
      $B/granflow-mpm $sc --backend cuda --bench 300 --warmup 20 $opts >>$log 2>&1
    done
  done
  TMO=100 run column 0.001 1e-5 fixed fp64 pt
  TMO=100 run column 0.001 1e-5 fixed fp64 pt --g2p-regcap on
  TMO=100 run column 0.001 1e-5 fixed fp32 pt
  TMO=150 run flume 0.005 1e-5 fixed fp64 pt
  TMO=150 run flume 0.005 1e-4 cfl:0.5 fp64 pt
  TMO=150 run flume 0.005 1e-4 cfl:0.5 fp32 pt
elif [ "$part" = 3d ]; then
  for prec in fp32 fp64; do
    for opts in "" "--g2p-split on" "--g2p-split on --g2p-regcap on" "--p2g tile" "--sort 0 --p2g atomic"; do
      [ $prec = fp64 ] && [ -n "$opts" ] && [ "$opts" != "--g2p-split on" ] && continue
      echo "== bench 3D slab $prec $opts" >>$log
      timeout 200 $B/granflow bench mpm mpm/scenes/column_collapse_3d.toml --steps 30 --warmup 5 --split 20 \
        --backend cuda --precision $prec $opts >>$log 2>&1
    done
  done
elif [ "$part" = final ]; then
  timeout 60 $B/tests/cuda/constitutive_device_host >>$log 2>&1; echo "constitutive_device_host exit $?" >>$log
  OMP_NUM_THREADS=8 timeout 150 $B/mpm_cuda_check --short >>$log 2>&1; echo "mpm_cuda_check exit $?" >>$log
  for sc in column flume; do
    echo "== bench $sc pt" >>$log
    $B/granflow-mpm $sc --backend cuda --bench 300 --warmup 20 >>$log 2>&1
  done
  TMO=100 run column 0.001 1e-5 fixed fp64 pt
  TMO=100 run column 0.001 1e-5 fixed fp32 pt
  TMO=150 run flume 0.005 1e-5 fixed fp64 pt
  TMO=150 run flume 0.005 1e-4 cfl:0.5 fp32 pt
  TMO=150 run flume 0.005 1e-4 cfl:0.5 fp64 pt
  TMO=100 run flume 0.005 1e-6 fixed fp64 pt --stop-after 0.4
  if [ -n "${FINAL_EXTRA:-}" ]; then  # further runs, e.g. a CUDA option against the default
    TMO=100 run column 0.001 1e-5 fixed fp64 pt $FINAL_EXTRA
    TMO=100 run column 0.001 1e-5 fixed fp32 pt $FINAL_EXTRA
  fi
  if [ "${GRANFLOW_MPM_CUDA_3D:-OFF}" = ON ]; then  # the 3D slab, 8e6 points (issue 7's scale target)
    for prec in fp32 fp64; do
      echo "== bench 3D slab $prec" >>$log
      timeout 200 $B/granflow bench mpm mpm/scenes/column_collapse_3d.toml --steps 30 --warmup 5 --split 20 \
        --backend cuda --precision $prec >>$log 2>&1
    done
  fi
  if [ -z "${NO_SANITIZE:-}" ]; then
    CS=$(command -v compute-sanitizer || ls /usr/local/cuda*/bin/compute-sanitizer | head -1)
    for run in "column_collapse_ci.toml" "flume_ci.toml" "column_collapse_ci.toml --g2p-split on"; do
      set -- $run
      for tool in memcheck racecheck; do
        timeout 150 $CS --tool $tool --error-exitcode 9 $B/granflow mpm mpm/scenes/$run --backend cuda --stop-after 0.07 \
          --out /tmp/san --force --no-png --quiet >/tmp/san.log 2>&1
        echo "$tool $run: exit $? | $(grep -E 'ERROR SUMMARY|RACECHECK SUMMARY' /tmp/san.log | head -1)" >>$log
      done
    done
  fi
else
  TMO=250 run flume 0.005 1e-6 fixed fp64 pt --stop-after 0.9
  TMO=250 run flume 0.0025 1e-4 cfl:0.5 fp64 pt
fi
(cd $R && find . -name "*.csv" | tar czf $OUT/$part.tgz -T -)
tail -c 5000 $log
cat $csv
