#!/bin/sh
# MPI cases of granflow ensemble and calibrate (issue 27; docs/mpm_ensembles.md, "Several
# processes (MPI)"): run by ctest as  mpi_cases.sh CASE GRANFLOW SOURCE_DIR WORK_DIR  with
# mpirun -np 2 --oversubscribe on the CPU twin, scenes shrunk to seconds.
set -u
case_name=$1 G=$2 SRC=$3 W=$4
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMP_NUM_THREADS=1
# Sanitizer build: Open MPI's libraries have no frame pointers, so LeakSanitizer needs the slow
# unwinder to see their frames and apply scripts/lsan_openmpi.supp; plugins stay loaded to be named.
export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}fast_unwind_on_malloc=0" OMPI_MCA_mca_base_component_disable_dlclose=1
MPIRUN="mpirun -np 2 --oversubscribe"
SCENE=$SRC/mpm/scenes/column_collapse_ci.toml
fail() { echo "FAIL: $*"; exit 1; }
rm -rf "$W" && mkdir -p "$W" && cd "$W" || exit 1

# The CI column on a 20 mm grid, CONS s consolidation (default 0.06), DUR s of collapse (fixed
# step 2e-4 s): sets DUR [CONS].
sets() {
  echo "\"grid.h=0.02\", \"grid.size=[0.6, 0.16]\", \"time.dt=2e-4\", \"stage[0].duration=${2:-0.06}\", \"stage[1].duration=$1\", \"output.times=[0.02, $1]\", \"output.series_dt=0.01\""
}
set_args() {
  echo "--set grid.h=0.02 --set grid.size=[0.6,0.16] --set time.dt=2e-4 --set stage[0].duration=0.06 --set stage[1].duration=$1 --set output.times=[0.02,$1] --set output.series_dt=0.01"
}
cat > design4.toml <<'D'
[design]
method = "lhs"
members = 4
seed = 1
[[vary]]
key = "frictional.phi_c_deg"
range = [18.0, 22.0]
[[vary]]
key = "material.e0"
range = [0.93, 0.97]
D
# job ITERATIONS DURATION [CONSOLIDATION]: ES-MDA over phi_c with 4 members, no polish
job() {
  cat <<J
params = "column_collapse"
[algorithm]
method = "ensemble"
[ensemble]
members = 4
iterations = $1
seed = 3
polish = false
[[free]]
key = "frictional.phi_c_deg"
lower = 15.0
upper = 25.0
[[experiments]]
kind = "mpm_scene"
name = "column"
scene = "$SCENE"
set = [$(sets "$2" "${3:-0.06}")]
backend = "cpu"
progress = false
[experiments.surface]
data = "surface.csv"
sd = 0.004
[experiments.front]
data = "front.csv"
J
}
printf 'x,y\n0.01,0.09\n0.05,0.078\n0.09,0.066\n0.13,0.054\n0.17,0.042\n0.21,0.03\n0.25,0.018\n0.29,0.006\n' > surface.csv
printf 't,x\n0.02,0.21\n0.04,0.22\n' > front.csv

# Files of calibrate that hold no wall times must be equal byte for byte.
same_calibration() {
  for f in posterior.csv posterior_summary.csv posterior_correlation.csv ensemble_curves.csv curves.csv fitted.toml; do
    cmp "$1/$f" "$2/$f" || fail "$1/$f and $2/$f differ"
  done
  # iterations.csv: all but the batch's seconds (last column)
  [ "$(cut -d, -f1-4 "$1/iterations.csv")" = "$(cut -d, -f1-4 "$2/iterations.csv")" ] || fail "iterations.csv differ"
}

case $case_name in
ensemble_equal)  # 4 members over 2 ranks = one process, bit for bit (fixed step)
  $G ensemble "$SCENE" design4.toml $(set_args 0.1) --out one --no-png --quiet > one.txt 2>&1 || fail "one process: $(cat one.txt)"
  $MPIRUN $G ensemble "$SCENE" design4.toml $(set_args 0.1) --out two --no-png --quiet > two.txt 2>&1 || fail "2 ranks: $(cat two.txt)"
  grep -q 'over 2 ranks' two.txt || fail "no '2 ranks' line: $(cat two.txt)"
  # summary.csv: all columns but wall_s (12) and message
  [ "$(cut -d, -f1-11 one/summary.csv)" = "$(cut -d, -f1-11 two/summary.csv)" ] || fail "summary.csv differs"
  [ "$(wc -l < two/summary.csv)" -eq 5 ] || fail "summary.csv has not 4 members"
  for k in 0000 0001 0002 0003; do
    for f in runout.csv tracked.csv profile_final.csv; do
      cmp "one/member_$k/$f" "two/member_$k/$f" || fail "member_$k/$f differs"
    done
  done
  grep -q '^# status: complete' two/granflow.manifest || fail "no complete manifest"
  grep -q 'member_0003/runout.csv' two/granflow.manifest || fail "the manifest misses rank 1's members"
  ;;
calibrate_equal)  # one ES-MDA iteration over 2 ranks = one process (short: 0.03 s + 0.02 s)
  printf 't,x\n0.01,0.205\n0.02,0.21\n' > front.csv
  job 1 0.02 0.03 > job.toml
  $G calibrate job.toml --out one --no-plot --quiet --threads 1 > one.txt 2>&1 || fail "one process: $(cat one.txt)"
  $MPIRUN $G calibrate job.toml --out two --no-plot --quiet --threads 1 > two.txt 2>&1 || fail "2 ranks: $(cat two.txt)"
  same_calibration one two
  [ ! -e two.esmda-state ] || fail "the state file outlived a completed run"
  ;;
rank_killed)  # a rank SIGKILLed mid-run ends the job; the rerun continues from the saved state
  job 2 0.3 > job.toml
  $G calibrate job.toml --out ref --no-plot --quiet --threads 1 > ref.txt 2>&1 || fail "reference: $(cat ref.txt)"
  $MPIRUN $G calibrate job.toml --out run --no-plot --quiet --threads 1 > run.txt 2>&1 &
  mpirun_pid=$!
  i=0
  while [ ! -e run.esmda-state ] && [ $i -lt 600 ]; do sleep 0.05; i=$((i + 1)); done
  [ -e run.esmda-state ] || fail "no state file after 30 s: $(cat run.txt)"
  victim=
  for p in $(ps -o pid= --ppid $mpirun_pid); do
    tr '\0' '\n' < /proc/$p/environ 2>/dev/null | grep -qx 'OMPI_COMM_WORLD_RANK=1' && victim=$p
  done
  [ -n "$victim" ] || fail "rank 1 not found among the children of mpirun"
  kill -KILL "$victim"
  wait $mpirun_pid && fail "mpirun exited 0 with rank 1 killed"
  grep -qi 'rank 1' run.txt || fail "mpirun did not name rank 1: $(cat run.txt)"
  [ ! -e run ] || fail "an output folder was claimed after the kill"
  [ -e run.esmda-state ] || fail "the state file is gone"
  $MPIRUN $G calibrate job.toml --out run --no-plot --threads 1 > again.txt 2>&1 || fail "rerun: $(cat again.txt)"
  grep -q 'resuming the ensemble at iteration' again.txt || fail "the rerun did not resume: $(cat again.txt)"
  same_calibration ref run
  [ ! -e run.esmda-state ] || fail "the state file outlived the completed rerun"
  ;;
rank_fails)  # rank 1 cannot write its member files: the run ends naming rank 1 and its host, no manifest
  mpirun -np 1 $G ensemble "$SCENE" design4.toml $(set_args 0.1) --out o --no-png --quiet : \
    -np 1 env GRANFLOW_FAULT_FILE=member_0003/runout GRANFLOW_FAULT_ERRNO=ENOSPC \
    $G ensemble "$SCENE" design4.toml $(set_args 0.1) --out o --no-png --quiet > o.txt 2>&1 \
    && fail "exit 0 with a failed rank"
  grep -q "granflow: error (rank 1 of 2 on host $(hostname)): .*member_0003/runout.csv" o.txt || fail "message: $(cat o.txt)"
  [ ! -e o/granflow.manifest ] || fail "a manifest claims the folder complete"
  ;;
one_process_only)  # commands other than ensemble and calibrate refuse several ranks
  $MPIRUN $G mpm "$SCENE" --out m --no-png > m.txt 2>&1 && fail "mpm ran under 2 ranks"
  grep -q 'granflow mpm runs in one process' m.txt || fail "message: $(cat m.txt)"
  ;;
*) fail "unknown case $case_name" ;;
esac
echo "ok: $case_name"
