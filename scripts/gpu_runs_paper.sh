#!/usr/bin/env bash
# GPU session for the paper's scenes (run on the GPU machine from the repository root, $OUT set):
#   scripts/gpu_runs_paper.sh column   checks, column benchmark, 1 mm runs, mesh series
#   scripts/gpu_runs_paper.sh flume    flume benchmark, 5 mm runs, mesh series
#   scripts/gpu_runs_paper.sh physics  after the MPM physics fixes (docs/mpm.md "Physics gaps"):
#                                      1 mm column both models, mesh series at a constant CFL
#                                      number and at dt 1e-5, scheme comparisons, 5 mm flume
# Logs and CSVs are packed into $OUT/<part>.tgz; every run's summary goes to $OUT/<part>.log.
set -uo pipefail
part=${1:-column}
B=build-gpu
[ -x $B/granflow-mpm ] || scripts/gpu_build.sh >/dev/null
R=/tmp/gf_runs
mkdir -p $R
log=$OUT/$part.log
run() {  # run NAME ARGS...: one granflow-mpm run, its summary in the log, its CSVs kept
  local name=$1
  shift
  echo "== $name: granflow-mpm $*" >>$log
  local t0=$SECONDS
  timeout ${TMO:-90} $B/granflow-mpm "$@" --out $R/$name 2>&1 | tr '\r' '\n' | grep -v "steps/s  ETA" >>$log
  echo "   [$name: exit ${PIPESTATUS[0]}, $((SECONDS - t0)) s]" >>$log
}
if [ "$part" = column ]; then
  $B/tests/cuda/constitutive_device_host >>$log 2>&1
  OMP_NUM_THREADS=8 $B/mpm_cuda_check --short >>$log 2>&1
  for m in pt frictional; do
    echo "== bench column 1 mm $m" >>$log
    $B/granflow-mpm column --backend cuda --model $m --bench 300 --warmup 20 >>$log 2>&1
  done
  run col1_pt column --backend cuda --model pt
  run col1_fr column --backend cuda --model frictional
  for h in 0.01 0.005 0.0025; do run col_${h}_pt column --backend cuda --model pt --h $h; done
  run col1_pt_linear column --backend cuda --model pt --shape linear --stop-after 0.2
elif [ "$part" = physics ]; then
  # ordered by importance; every run capped so the whole part fits one 10-minute call
  OMP_NUM_THREADS=8 timeout 120 $B/mpm_cuda_check --short >>$log 2>&1; echo "mpm_cuda_check exit $?" >>$log
  run col1_pt column --backend cuda --model pt
  run col1_fr column --backend cuda --model frictional
  for hd in "0.01 1e-4" "0.005 5e-5" "0.0025 2.5e-5"; do
    set -- $hd
    run col_${1}_pt column --backend cuda --model pt --h $1 --dt $2
    run col_${1}_fr column --backend cuda --model frictional --h $1 --dt $2
  done
  run fl5_pt_dt1e-5 flume --backend cuda --model pt --dt 1e-5
  run fl5_fr_dt1e-5 flume --backend cuda --model frictional --dt 1e-5
  for h in 0.02 0.01 0.0025; do run fl_${h}_pt_dt1e-5 flume --backend cuda --model pt --h $h --dt 1e-5; done
  TMO=150 run fl5_pt flume --backend cuda --model pt
else
  echo "== bench flume 5 mm pt" >>$log
  $B/granflow-mpm flume --backend cuda --model pt --bench 300 --warmup 20 >>$log 2>&1
  run fl5_pt flume --backend cuda --model pt
  run fl5_fr flume --backend cuda --model frictional
  for h in 0.02 0.01; do run fl_${h}_pt flume --backend cuda --model pt --h $h; done
fi
(cd $R && find . -name "*.csv" | tar czf $OUT/$part.tgz -T -)
tail -c 6000 $log
