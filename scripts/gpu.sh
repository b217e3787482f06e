#!/usr/bin/env bash
# GPU sessions, in named parts, on a machine with only CMake, nvcc and .deps/include (made by
# scripts/copy_deps.sh where the headers are installed). Every run is granflow mpm or granflow
# bench mpm on a scene file of mpm/scenes, changed with --set.
#
#   scripts/gpu.sh PART [PART...]
#
#   build          configure and build $BUILD: granflow, mpm_cuda_check, constitutive_device_host
#   check          host/device constitutive test; GPU against CPU twin (mpm_cuda_check --short;
#                  CHECK_ARGS=--ensembles: the ensemble cases only)
#   paper          the paper's scenes at full size: benchmarks; 1 mm column, both models and the
#                  three precisions; 5 mm flume at dt 1e-5, both models, and at the paper's 1e-6
#                  (first 0.4 s); transfer and shape variants of the 1 mm column
#   series         mesh series, one row per run in series.csv (scripts/plot_error_vs_time.py):
#                  series-column  column 10/5/2.5/1 mm, fixed and CFL step, fp64 and fp32, the
#                                 frictional model and linear shapes at 5 mm and 1 mm
#                  series-flume   flume 20/10/5 mm, the same axes
#                  series-fine    flume 2.5 mm (CFL step), the 5 mm flume at the paper's dt (capped)
#   perf           granflow bench mpm of the CUDA options on the 1 mm column and the 5 mm flume,
#                  the precisions, the split G2P; the full 1 mm column and its first 0.35 s timed
#   profile        Nsight Compute of the 1 mm column's kernels (needs ncu)
#   profile-ensemble  Nsight Compute of the 64-member 5 mm column's step kernels in the collapse
#   sanitize       compute-sanitizer memcheck and racecheck of the CI scenes and CUDA option variants
#   sanitize-ensemble  compute-sanitizer memcheck, racecheck and synccheck of an 8-member ensemble of
#                  the CI column (the samples' snapshots on a second stream)
#   3d             the 3D slab (8e6 points) benchmark: precisions and CUDA options
#   ensemble       granflow ensemble against sequential single runs of the same members: 64
#                  members of the 5 mm column (fp32, fp64), 16 of the 1 mm column (fp32)
#   study          the flume parameter study (mpm/scenes/ensembles/flume_study.toml, 64 members,
#                  lifting gate, 0.8 s of flow, CFL step), summary in study_summary.csv
#   loadcell-pt, loadcell-fr  the load-cell flume (mpm/scenes/loadcell, docs/mpm_results.md) at
#                  45-65 deg, phase-transition or frictional-only model, 2 s of flow, CFL step
#   loadcell-ens   the 45 deg load-cell flume's peak force over flume_study.toml (64 members,
#                  fp32, 1.5 s of flow, 5 ms force samples); analysis: scripts/loadcell_study.py
#   slabs          one scene over 2 GPUs (needs 2): mpm_cuda_check --slabs; the 3D slab's strong
#                  scaling (--stop-after 0.15, fp32) and the slab widened to 6.4e7 points (bench
#                  mpm), on 2 and 1 GPUs
#   cylinder       the axisymmetric collapse (issue 53; scripts/make_cylinder_collapse.py, fp32,
#                  the column_collapse set): CYL_CASES="A H [VARIANT [ARGS...]]; ..." (default: the
#                  series a = 1, 2, 4 at R0/h = 12.5 and 25), a VARIANT's ARGS going to granflow mpm
#                  but --gen-KEY=VALUE, which goes to the generator as --KEY VALUE (--gen-model=frictional,
#                  --gen-duration=0.5); one row per run in cylinder.csv
#                  (scripts/cylinder_summary.py); CYL_RESUME=1 continues a case capped by TMO in an
#                  earlier call on the same machine from its checkpoint (RUNS must persist)
#   series-3d      the 3D slab and the valley at several grids (SLAB_H, VALLEY_H), fp32, whole runs
#                  with the step in proportion to h: series3d.csv
#   meshformats    the STL barrier of valley_barrier_ci.toml also as OBJ and PLY, GPU against CPU twin
#   frames         the host time outside the steps of the 3D slab (8e6 points, --stop-after 0.15,
#                  fp32, one GPU): whole command, run wall, device time of the spans; BASE_G=PATH
#                  (with BASE_SC, the scene folder of that tree) runs an earlier build first, in
#                  the same call
#   ensemble-batched  the batched runs of the ensemble part only, the 5 mm one also sampled
#                  sparsely (ENS_1MM=0: without the 1 mm ensemble)
#   ensemble-diag  the 64-member column sampled sparsely; a 1 mm member alone, twice
#   ensemble-options  the 64-member 5 mm column under the CUDA options (split G2P, sort, blocks)
#   calibrate      data/calibration/bui_column.toml (5 mm), then the 1 mm column with the fitted set
#   flow           the collisional options of issue 25 (data/params/column_collapse_flow.toml) on the
#                  1 mm column against MODEL.md's model: cost per step (benchmarks) and the whole
#                  run in fp64 and fp32 (run-out, final surface in the run folders); run check first
#                  (its last case is host/device agreement with every option on)
#
# Results go to $GPU_OUT, else $OUT, else out/gpu: PART.log (each command, printed before it
# runs, and its output), series.csv, PART_csv.tgz (the runs' CSV outputs); stdout has the
# commands and one line of figures per run. Run folders go to $RUNS (default /tmp/gf_gpu).
# Environment: BUILD (build-gpu), CUDA_ARCH (90), GRANFLOW_MPM_CUDA_3D (ON: the 3d part needs
# it), TMO (seconds cap of each run; default per run), KILL_AFTER (30: seconds a
# capped run has for its checkpoint after SIGTERM before SIGKILL; the R0/h 80 cylinder, 3.2e6
# points, wrote none within 30 s), SANITIZE_TOOLS ("memcheck racecheck"),
# BACKEND (cuda; cpu tries the runs on the CPU twin). Sourced, the script only defines its
# functions (series, run, bench: for single runs by hand).
set -o pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.." || exit 1

B=${BUILD:-build-gpu}
G=$B/granflow
RES=${GPU_OUT:-${OUT:-out/gpu}}
RUNS=${RUNS:-/tmp/gf_gpu}
BACKEND=${BACKEND:-cuda}
SC=mpm/scenes
COL=$SC/column_collapse.toml
COL_FR=$SC/column_collapse_frictional.toml
FLU=$SC/flume.toml
FLU_FR=$SC/flume_frictional.toml
CSV=$RES/series.csv
log=/dev/null  # the current part's log
R=$RUNS        # the current part's run folder

# The words as a shell reads them back (quoted where needed).
words() {
  local w out=
  for w in "$@"; do
    if [[ $w =~ ^[A-Za-z0-9_./=:,+@%-]+$ ]]; then out+=" $w"; else out+=" '${w//\'/\'\\\'\'}'"; fi
  done
  printf '%s\n' "${out# }"
}

# x CAP FILE CMD...: prints CMD, runs it capped at CAP seconds with its output in FILE (of the
# progress lines only the last) and in the part's log; returns CMD's exit code (124: capped).
x() {
  local cap=$1 file=$2
  shift 2
  mkdir -p "$(dirname "$file")"
  echo "+ $(words "$@")" | tee -a "$log"
  timeout -k "${KILL_AFTER:-30}" "$cap" "$@" >"$file.raw" 2>&1
  local rc=$?
  tr '\r' '\n' <"$file.raw" | awk '/steps\/s  ETA/ {last = $0; next} {print} END {if (last != "") print last}' >"$file"
  rm -f "$file.raw"
  cat "$file" >>"$log"
  echo "  [exit $rc]" >>"$log"
  return $rc
}

# The figures of a granflow bench mpm report on one line.
bench_figures() {
  awk -v l="$1" '/^time per step/ {t = $4} /device time per step/ {d = $(NF - 1)} /^  P2G:/ {p = $2}
    /^  grid update:/ {g = $3} /^  G2P \+ constitutive:/ {c = $4} /^  sort \(amortised\)/ {s = $(NF - 1)}
    /^particle-updates/ {u = $2} /^set-up/ {su = $2 "+" $7 " s"}
    END {printf "  %-46s %8s us/step (device %7s) | split: P2G %7s grid %6s G2P %7s sort %5s | %9s updates/s | set-up %s\n",
                l, t, d, p, g, c, s, u, su}' "$2"
}

# bench LABEL CAP SCENE ARGS...: granflow bench mpm on the GPU, its figures on one line; the
# report stays in $bench_file.
bench() {
  local label=$1 cap=$2 scene=$3
  shift 3
  bench_file=$R/bench_$(printf %s "$label" | tr -c 'a-zA-Z0-9.-' _).txt
  x "$cap" "$bench_file" "$G" bench mpm "$scene" --backend "$BACKEND" "$@" || echo "  ($label: exit code $?, see $log)"
  bench_figures "$label" "$bench_file"
}

# The figures of a granflow mpm summary FILE on one line (a capped run: how far it got).
run_figures() {
  awk -v l="$1" -v rc="$2" '/^steps:/ {n = $2} /^wall:/ {w = $2} /^final run-out:/ {r = $3} /^final height:/ {h = $3}
    /device time per step \(spans\)/ {d = $6} /after stage 1:/ {b = $6 "/" $12 " Pa"}
    /interrupted by SIG/ {cap = $8} /run stopped/ {stop = $0}
    END {if (rc == 0) printf "  %-24s run-out %s m, height %s m, %s steps, wall %s s, device %s us/step, base %s\n",
                             l, r, h, n, w, d, b;
         else printf "  %-24s exit %s%s %s\n", l, rc, cap != "" ? ", stopped at t = " cap " s" : "", stop}' "$3"
}

# run NAME CAP SCENE ARGS...: granflow mpm SCENE on the GPU into $R/NAME (capped at TMO if set,
# else CAP seconds); one line of figures.
run() {
  local name=$1 cap=$2 scene=$3
  shift 3
  x "${TMO:-$cap}" "$R/$name.txt" "$G" mpm "$scene" --backend "$BACKEND" --out "$R/$name" --force --no-png "$@"
  local rc=$?
  run_figures "$name" $rc "$R/$name.txt"
  return $rc
}

# Run-out at t_flow = T in a run's runout.csv (t,t_flow,stage,runout,...).
runout_at() {
  awk -F, -v t="$2" 'NR > 1 && $2 > t - 1e-6 && $2 < t + 1e-6 {r = $4} END {print r}' "$1" 2>/dev/null
}

# series SCENE H DT MODE PRECISION MODEL [ARGS...]: one run of a mesh series, one row of series.csv.
# MODE is fixed or cfl:C (adaptive step, DT the largest); MODEL pt or frictional; ARGS go to the
# run and, as given, to the row's extra column.
series() {
  local scene=$1 h=$2 dt=$3 mode=$4 prec=$5 model=$6
  shift 6
  local extra="$*" file=$COL cap=120
  local args=(--set "grid.h=$h" --set "time.dt=$dt" --precision "$prec")
  if [ "$scene" = flume ]; then
    file=$FLU
    cap=150
    # the grid's height a whole number of cells (flume.toml: 2.155 m, 431 cells of 5 mm)
    case $h in
      0.02 | 0.01) args+=(--set "grid.size=[3.2, 2.16]") ;;
      0.0025) args+=(--set "grid.size=[3.2, 2.1525]") ;;
    esac
  elif awk -v h="$h" 'BEGIN {exit !(h >= 0.005)}'; then
    args+=(--set output.series_dt=5e-3)  # the coarse columns sampled as before
  fi
  [ "$model" = frictional ] && args+=(--set material.model=frictional)
  [ "${mode%%:*}" = cfl ] && args+=(--set time.adaptive=true --set "time.cfl=${mode#cfl:}")
  local name
  name=${scene}_${h}_${mode/:/}_${prec}_${model}$(printf %s "${extra:+_$extra}" | tr -c 'a-zA-Z0-9.' _)
  mkdir -p "$RES"
  [ -f "$CSV" ] || echo "scene,h_mm,dt_mode,dt_max,precision,model,exit,steps,wall_s,device_us_per_step,runout_0.4,runout_0.8,runout_final,height_final,t_end,extra" >"$CSV"
  local t0=$SECONDS
  x "${TMO:-$cap}" "$R/$name.txt" "$G" mpm "$file" --backend "$BACKEND" --out "$R/$name" --force --no-png "${args[@]}" "$@"
  local rc=$?
  local r4 r8
  r4=$(runout_at "$R/$name/runout.csv" 0.4)
  r8=$(runout_at "$R/$name/runout.csv" 0.8)
  awk -v scene="$scene" -v h="$h" -v mode="$mode" -v dt="$dt" -v prec="$prec" -v model="$model" -v rc=$rc \
      -v wall=$((SECONDS - t0)) -v r4="$r4" -v r8="$r8" -v extra="${extra//,/;}" '
    /^steps:/ {steps = $2} /^wall:/ {wall = $2} /^final run-out:/ {ro = $3} /^final height:/ {ht = $3}
    /^simulated:/ {tend = $2} /device time per step \(spans\)/ {dev = $6}
    /^ *t = / {reached = $3}
    /interrupted by SIG/ {stopped = $8; steps = $11; sub(/\);?$/, "", steps)}
    END {
      if (tend == "") tend = stopped != "" ? stopped : reached  # capped: how far it got
      printf "%s,%g,%s,%s,%s,%s,%d,%s,%s,%s,%s,%s,%s,%s,%s,%s\n", scene, h * 1000, mode, dt, prec, model, rc,
             steps, wall, dev, r4, r8, ro, ht, tend, extra
    }' "$R/$name.txt" | tee -a "$CSV"
}

part_cylinder() {
  local cases=${CYL_CASES:-"1 0.008; 2 0.008; 4 0.008; 1 0.004; 2 0.004; 4 0.004"}
  local c dirs=() IFS_old=$IFS
  IFS=';'
  local list=($cases)
  IFS=$IFS_old
  for c in "${list[@]}"; do
    # shellcheck disable=SC2086
    set -- $c
    local a=$1 h=$2 variant=${3:-} gen=()
    shift 2
    [ $# -gt 0 ] && shift
    local dir=$R/cyl_a${a}_h${h}${variant:+__$variant} args=()
    for w in "$@"; do
      case $w in
        --gen-*=*) w=${w#--gen-}; gen+=("--${w%%=*}" "${w#*=}") ;;  # to the generator
        *) args+=("$w") ;;
      esac
    done
    if [ "${CYL_RESUME:-0}" = 1 ] && [ -f "$dir/run/checkpoint.bin" ]; then
      # the same case, interrupted by its cap in an earlier call on this machine: continue it
      x "${TMO:-590}" "$dir/run.txt" "$G" mpm "$dir/scene.toml" --backend "$BACKEND" --out "$dir/run" --restart --no-png \
        "${args[@]}"
    else
      python3 scripts/make_cylinder_collapse.py "$dir" --a "$a" --h "$h" "${gen[@]}" >>"$log" || return 1
      x "${TMO:-590}" "$dir/run.txt" "$G" mpm "$dir/scene.toml" --backend "$BACKEND" --out "$dir/run" --force --no-png \
        "${args[@]}"
    fi
    echo $? >"$dir/exit"
    cat "$dir/run.txt" >>"$dir/runs.txt"  # every call's summary (run.txt holds the last)
    dirs+=("$dir")
    python3 scripts/cylinder_summary.py "$dir" | tail -1 | tee -a "$log"
    # the run's CSVs and final thickness map, for the analysis off the machine (a few MB)
    local keep=$RES/cyl/$(basename "$dir")
    mkdir -p "$keep"
    cp "$dir/scene.toml" "$dir"/run/*.csv "$keep/" 2>/dev/null
    [ -f "$dir/run/maps/deposit_thickness.asc" ] && gzip -c "$dir/run/maps/deposit_thickness.asc" >"$keep/deposit_thickness.asc.gz"
  done
  python3 scripts/cylinder_summary.py "${dirs[@]}" >"$RES/cylinder.csv"
}

# The 3D slab (column_collapse_3d.toml) and the valley (valley.toml) at several grids (issue 53),
# fp32, the step in proportion to h (the scenes' 1e-5 s at 1 mm), whole runs: one line per run
# in series3d.csv. SLAB_H and VALLEY_H: the grids [m].
part_series_3d() {
  local h dt name scene
  echo "scene,h_mm,dt_s,steps,wall_s,device_us_per_step,runout_m,height_m,exit" >"$RES/series3d.csv"
  for scene in slab valley; do
    local hs=${SLAB_H:-"0.01 0.005 0.0025"} file=$SC/column_collapse_3d.toml
    [ $scene = valley ] && hs=${VALLEY_H:-"0.02 0.01 0.005 0.0025"} file=$SC/valley.toml
    for h in $hs; do
      dt=$(python3 -c "print(f'{$h * 1e-2:.6g}')")
      name=${scene}_h$h
      run "$name" 590 "$file" --precision fp32 --set "grid.h=$h" --set "time.dt=$dt"
      local rc=$?
      awk -v s=$scene -v h="$h" -v dt="$dt" -v rc=$rc '/^steps:/ {n = $2} /^wall:/ {w = $2}
        /device time per step \(spans\)/ {d = $6} /^final run-out:/ {r = $3} /^final height:/ {z = $3}
        END {printf "%s,%g,%s,%s,%s,%s,%s,%s,%s\n", s, h * 1000, dt, n, w, d, r, z, rc}' "$R/$name.txt" >>"$RES/series3d.csv"
    done
  done
  cat "$RES/series3d.csv"
}

# The slit barrier of valley_barrier_ci.toml read as STL, OBJ and PLY (written here from the STL)
# on both back ends: deposit.csv and runout.csv compared byte for byte, obstacle_forces.csv
# value by value (largest difference of each column).
part_meshformats() {
  local f b d=$R/meshformats
  mkdir -p "$d/valley"
  cp $SC/valley/*.asc "$d/valley/"
  python3 - "$SC/valley/slit_barrier.stl" "$d/valley/slit_barrier" <<'PY' || return 1
import sys
v, tris = [], []
for line in open(sys.argv[1]):
    w = line.split()
    if w and w[0] == "vertex":
        v.append(tuple(w[1:4]))
for i in range(0, len(v), 3):
    tris.append((i, i + 1, i + 2))
with open(sys.argv[2] + ".obj", "w") as o:
    o.write("o barrier\n" + "".join(f"v {a} {b} {c}\n" for a, b, c in v))
    o.write("".join(f"f {i + 1} {j + 1} {k + 1}\n" for i, j, k in tris))
with open(sys.argv[2] + ".ply", "w") as o:
    o.write(f"ply\nformat ascii 1.0\nelement vertex {len(v)}\nproperty float x\nproperty float y\nproperty float z\n"
            f"element face {len(tris)}\nproperty list uchar int vertex_indices\nend_header\n")
    o.write("".join(f"{a} {b} {c}\n" for a, b, c in v) + "".join(f"3 {i} {j} {k}\n" for i, j, k in tris))
PY
  cp $SC/valley/slit_barrier.stl "$d/valley/"
  for f in stl obj ply; do
    sed "s|valley/slit_barrier.stl|valley/slit_barrier.$f|" $SC/valley_barrier_ci.toml >"$d/barrier_$f.toml"
    for b in cuda cpu; do
      x 300 "$d/$f.$b.txt" "$G" mpm "$d/barrier_$f.toml" --backend $b --out "$d/$f.$b" --force --no-png
      echo "  $f $b: exit $?, $(grep -h "^final run-out:" "$d/$f.$b.txt")"
    done
  done
  for f in stl obj ply; do
    for b in deposit runout; do
      cmp -s "$d/$f.cuda/$b.csv" "$d/stl.cpu/$b.csv" && echo "  $f cuda $b.csv: identical to stl cpu" ||
        echo "  $f cuda $b.csv: DIFFERS from stl cpu"
    done
    python3 - "$d/$f.cuda/obstacle_forces.csv" "$d/stl.cpu/obstacle_forces.csv" "$f" <<'PY'
import csv, sys
a, b = (list(csv.DictReader(open(p))) for p in sys.argv[1:3])
worst = {}
for ra, rb in zip(a, b):
    for k in ra:
        try:
            x, y = float(ra[k]), float(rb[k])
        except ValueError:
            continue
        worst[k] = max(worst.get(k, 0.0), abs(x - y))
print(f"  {sys.argv[3]} cuda obstacle_forces.csv against stl cpu: {len(a)}/{len(b)} rows; largest differences",
      ", ".join(f"{k} {v:.3g}" for k, v in worst.items()))
PY
  done
}

part_build() {
  if [ ! -d .deps/include/Eigen ] || [ ! -d .deps/include/toml++ ]; then
    echo "no .deps/include: run scripts/copy_deps.sh where Eigen, toml++, CLI11 and libfccp are installed" >&2
    return 1
  fi
  local t0=$SECONDS
  x 600 "$R/configure.txt" cmake -S . -B "$B" -DGRANFLOW_GPU_ONLY=ON -DGRANFLOW_DEPS_INCLUDE="$PWD/.deps/include" \
    -DCMAKE_CUDA_ARCHITECTURES="${CUDA_ARCH:-90}" -DCMAKE_BUILD_TYPE=Release \
    -DGRANFLOW_MPM_CUDA_3D="${GRANFLOW_MPM_CUDA_3D:-ON}" || { tail -20 "$R/configure.txt"; return 1; }
  x 1800 "$R/build.txt" cmake --build "$B" -j"$(nproc)" --target granflow mpm_cuda_check constitutive_device_host ||
    { grep -E "error|Error" "$R/build.txt" | head -20; return 1; }
  echo "build: $((SECONDS - t0)) s" | tee -a "$log"
}

part_check() {
  local rc1 rc2
  nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm --format=csv,noheader 2>&1 | head -1 | tee -a "$log"
  x 60 "$R/device_host.txt" "$B/tests/cuda/constitutive_device_host"
  rc1=$?
  echo "  constitutive_device_host: exit code $rc1 (0: all OK)"
  tail -3 "$R/device_host.txt"
  x 300 "$R/cuda_check.txt" env OMP_NUM_THREADS=8 "$B/mpm_cuda_check" --short ${CHECK_ARGS:-}
  rc2=$?
  echo "  mpm_cuda_check --short: exit code $rc2 (0: all OK; 77: no GPU; run-out/height within 0.5 %, points in original order)"
  grep -E "OK|FAIL" "$R/cuda_check.txt" | cut -c1-160
  [ $rc1 -eq 0 ] && [ $rc2 -eq 0 ]
}

part_paper() {
  echo "== benchmarks (300 steps of the consolidation after 20)"
  bench "column 1 mm, phase transition" 90 "$COL" --steps 300 --warmup 20
  bench "column 1 mm, frictional only" 90 "$COL_FR" --steps 300 --warmup 20
  bench "flume 5 mm, phase transition" 90 "$FLU" --steps 300 --warmup 20
  echo "== 1 mm column, 0.1 s consolidation + 1 s collapse (1.1e5 steps)"
  run col1_pt 150 "$COL"
  run col1_fr 150 "$COL_FR"
  run col1_pt_mixed 150 "$COL" --precision mixed
  run col1_pt_fp32 150 "$COL" --precision fp32
  echo "== 5 mm flume, 0.1 s consolidation + 3 s flow"
  run fl5_pt_dt1e-5 150 "$FLU" --set time.dt=1e-5
  run fl5_fr_dt1e-5 150 "$FLU_FR" --set time.dt=1e-5
  run fl5_pt_paperdt 150 "$FLU" --stop-after 0.5  # dt 1e-6 as the paper: the first 0.4 s of flow
  echo "== 1 mm column variants: transfer and shape functions"
  run col1_pt_pic025 150 "$COL" --set solver.pic_speed=0.25
  run col1_pt_flip099 150 "$COL" --set solver.transfer=flip --set solver.pic_speed=0 --set solver.flip=0.99
  run col1_pt_linear 90 "$COL" --set grid.shape=linear --set solver.transfer=flip --stop-after 0.3
}

part_flow() {
  echo "== collisional options (issue 25): cost per step, 300 consolidation steps after 20"
  bench "column 1 mm, MODEL.md's model" 90 "$COL" --steps 300 --warmup 20
  bench "column 1 mm, options" 90 "$COL" --steps 300 --warmup 20 --params column_collapse_flow
  bench "column 1 mm, MODEL.md's model, fp32" 90 "$COL" --steps 300 --warmup 20 --precision fp32
  bench "column 1 mm, options, fp32" 90 "$COL" --steps 300 --warmup 20 --precision fp32 --params column_collapse_flow
  echo "== 1 mm column, 0.1 s consolidation + 1 s collapse, with the options"
  run col1_pt 150 "$COL"
  run col1_pt_flow 150 "$COL" --params column_collapse_flow
  run col1_pt_flow_fp32 150 "$COL" --params column_collapse_flow --precision fp32
}

part_series_column() {
  local hd prec
  for hd in "0.01 1e-4" "0.005 5e-5" "0.0025 2.5e-5"; do
    set -- $hd
    for prec in fp64 fp32; do
      series column "$1" "$2" fixed $prec pt
      series column "$1" 1e-4 cfl:0.5 $prec pt
    done
  done
  series column 0.005 5e-5 fixed fp64 frictional
  series column 0.005 5e-5 fixed fp64 pt --set grid.shape=linear --set solver.transfer=flip
  series column 0.001 1e-5 fixed fp64 pt  # the reference of plot_error_vs_time.py
  series column 0.001 1e-5 fixed fp64 frictional
  series column 0.001 1e-5 fixed fp32 pt
  series column 0.001 1e-4 cfl:0.5 fp64 pt
  series column 0.001 1e-4 cfl:0.5 fp32 pt
}

part_series_flume() {
  local h prec
  for h in 0.02 0.01 0.005; do
    for prec in fp64 fp32; do
      series flume $h 1e-5 fixed $prec pt
      series flume $h 1e-4 cfl:0.5 $prec pt
    done
  done
  series flume 0.005 1e-4 cfl:0.5 fp64 frictional
  series flume 0.005 1e-5 fixed fp64 frictional
}

part_series_fine() {
  TMO=${TMO:-250} series flume 0.0025 1e-4 cfl:0.5 fp64 pt
  TMO=${TMO:-250} series flume 0.005 1e-6 fixed fp64 pt --stop-after 0.9
}

part_perf() {
  local base="--loop step --graphs off --sort 0 --p2g atomic" c="--steps 300 --warmup 20"
  echo "== 1 mm column benchmark (80,000 points, 300 steps of the consolidation after 20)"
  bench "baseline-like (step loop, no graphs/sort, atomic)" 90 "$COL" $c $base
  bench "spans, no graphs, no sort, atomic P2G" 90 "$COL" $c --graphs off --sort 0 --p2g atomic
  bench "spans + graphs, no sort, atomic P2G" 90 "$COL" $c --sort 0 --p2g atomic
  bench "spans + graphs + sort 32, atomic P2G" 90 "$COL" $c --p2g atomic
  bench "spans + graphs + sort 32, tile P2G" 90 "$COL" $c --p2g tile
  bench "default (spans + graphs + sort 32 + warp P2G)" 90 "$COL" $c
  grep -hE "CUDA options|registers" "$bench_file"
  bench "default, sort every 8" 90 "$COL" $c --sort 8
  bench "default, no graphs" 90 "$COL" $c --graphs off
  bench "default, G2P <= 168 registers" 90 "$COL" $c --g2p-regcap on
  bench "default, G2P block 64" 90 "$COL" $c --g2p-block 64
  bench "default, G2P block 256" 90 "$COL" $c --g2p-block 256
  bench "default, G2P split off" 90 "$COL" $c --g2p-split off
  bench "default, G2P split on" 90 "$COL" $c --g2p-split on
  bench "default, G2P split on, <= 168 registers" 90 "$COL" $c --g2p-split on --g2p-regcap on
  bench "default, frictional only" 90 "$COL_FR" $c
  bench "default, mixed precision" 90 "$COL" $c --precision mixed
  bench "default, fp32" 90 "$COL" $c --precision fp32
  echo "== 5 mm flume benchmark (24,000 points, 283,386 nodes)"
  bench "flume baseline-like" 90 "$FLU" $c $base
  bench "flume spans + graphs, no sort, atomic P2G" 90 "$FLU" $c --sort 0 --p2g atomic
  bench "flume default" 90 "$FLU" $c
  bench "flume default, G2P split off" 90 "$FLU" $c --g2p-split off
  bench "flume default, G2P split on" 90 "$FLU" $c --g2p-split on
  bench "flume default, G2P split on, <= 168 registers" 90 "$FLU" $c --g2p-split on --g2p-regcap on
  echo "== full 1 mm column (1.1e5 steps, defaults), and its first 0.35 s baseline-like against the defaults"
  run col1_full 240 "$COL"
  run col035_baseline 120 "$COL" --stop-after 0.35 --span 1 --graphs off --sort 0 --p2g atomic
  run col035_default 120 "$COL" --stop-after 0.35
}

# The --set words of member K of an ensemble's summary.csv (the columns between member and status).
member_sets() {
  awk -F, -v k="$2" 'NR == 1 {for (i = 2; $i != "status"; ++i) key[i] = $i; n = i; next}
    $1 == k {for (i = 2; i < n; ++i) printf "--set %s=%s ", key[i], $i}' "$1"
}

# ens NAME CAP SCENE DESIGN ARGS...: granflow ensemble on the GPU into $R/NAME; one line of figures.
ens() {
  local name=$1 cap=$2 scene=$3 design=$4
  shift 4
  x "${TMO:-$cap}" "$R/$name.txt" "$G" ensemble "$scene" "$design" --backend "$BACKEND" --out "$R/$name" --force \
    --no-png --quiet "$@"
  local rc=$?
  awk -v l="$name" -v rc=$rc '/^members:/ {m = $2 " members, " $3 " " $4} /^particles:/ {n = $2} /^steps:/ {s = $2}
    /^wall:/ {w = $2} /^particle-updates/ {u = $2} /^wall per step/ {p = $4}
    END {printf "  %-24s exit %s: %s, %s points, %s steps, wall %s s (%s us/step), %s particle-updates/s\n",
                l, rc, m, n, s, w, p, u}' "$R/$name.txt"
  return $rc
}

# Member K's final run-out in an ensemble's summary.csv.
member_runout() {
  awk -F, -v k="$2" 'NR == 1 {for (i = 1; i <= NF; ++i) if ($i == "runout") c = i; next} $1 == k {print $c}' "$1"
}

part_ensemble() {
  local p k c5=(--set grid.h=0.005 --set time.dt=5e-5) t0 seq
  for p in fp32 fp64; do
    echo "== 64 members of the 5 mm column ($p): batched, then members 0-3 one after the other"
    ens "col5_64_$p" 300 "$COL" "$SC/ensembles/column_bench_64.toml" "${c5[@]}" --precision $p
    t0=$SECONDS
    for k in 0 1 2 3; do
      # shellcheck disable=SC2046  # member_sets prints words
      run "col5_${p}_m$k" 60 "$COL" "${c5[@]}" --precision $p $(member_sets "$R/col5_64_$p/summary.csv" $k)
      echo "    member $k run-out: ensemble $(member_runout "$R/col5_64_$p/summary.csv" $k) m, single $(awk '/^final run-out/ {print $3}' "$R/col5_${p}_m$k.txt") m"
    done
    seq=$((SECONDS - t0))
    echo "  sequential: 4 members in $seq s (process wall, set-up included): 64 members ~ $((16 * seq)) s"
  done
  echo "== 16 members of the 1 mm column (fp32): batched, then members 0-1 one after the other"
  ens col1_16_fp32 300 "$COL" "$SC/ensembles/column_bench_16.toml" --precision fp32
  for k in 0 1; do
    # shellcheck disable=SC2046
    run "col1_fp32_m$k" 60 "$COL" --precision fp32 $(member_sets "$R/col1_16_fp32/summary.csv" $k)
    echo "    member $k run-out: ensemble $(member_runout "$R/col1_16_fp32/summary.csv" $k) m, single $(awk '/^final run-out/ {print $3}' "$R/col1_fp32_m$k.txt") m"
  done
  cp "$R/col5_64_fp32/summary.csv" "$RES/ensemble_col5_64_fp32.csv" 2>/dev/null
  cp "$R/col1_16_fp32/summary.csv" "$RES/ensemble_col1_16_fp32.csv" 2>/dev/null
}

# The flume study: the front at 0.4 and 0.8 s against phi_c, e0, the base friction and the
# gate's lift speed (docs/mpm_ensembles.md). The gate moves to the release stage (flume_study.toml).
# Capped at STUDY_CAP seconds (SIGTERM: the summary holds what was reached); progress kept.
part_study() {
  x "${STUDY_CAP:-300}" "$R/flume_study.txt" "$G" ensemble "$FLU" "$SC/ensembles/flume_study.toml" --backend "$BACKEND" \
    --out "$R/flume_study" --force --no-png --set 'stage[1].gate.point=[0.35355, 1.27279]' \
    --set 'stage[1].gate.normal=[1.0, 0.0]' --set 'stage[1].duration=0.8' --set 'output.times=[0.4, 0.8]' \
    --set time.adaptive=true --set time.dt=1e-4 --precision fp32
  tail -c 600 "$R/flume_study.txt"
  cp "$R/flume_study/summary.csv" "$RES/study_summary.csv" 2>/dev/null
  tar czf "$RES/study_profiles.tgz" -C "$R/flume_study" $(cd "$R/flume_study" && ls -d member_*/profile_final.csv member_*/runout.csv) 2>/dev/null
}

# The load-cell flume: forces on the wall at the end of the slope (docs/mpm_results.md).
loadcell_runs() {
  local model=$1 a
  shift
  for a in 45 50 55 60 65; do
    run "${model}_$a" 240 "$SC/loadcell/loadcell_$a.toml" "$@"
    mkdir -p "$RES/loadcell/${model}_$a"
    cp "$R/${model}_$a"/{obstacle_forces,gauges,runout}.csv "$RES/loadcell/${model}_$a/" 2>/dev/null
  done
}
part_loadcell_pt() { loadcell_runs pt; }
part_loadcell_fr() { loadcell_runs fr --set material.model=frictional; }
part_loadcell_ens() {
  ens lc45_study "${STUDY_CAP:-500}" "$SC/loadcell/loadcell_45.toml" "$SC/ensembles/flume_study.toml" \
    --set 'stage[1].gate.point=[0.35355, 1.27279]' --set 'stage[1].gate.normal=[1.0, 0.0]' \
    --set 'stage[1].duration=1.5' --set 'output.times=[1.5]' --set output.series_dt=0.005 --precision fp32
  tail -c 400 "$R/lc45_study.txt"
  mkdir -p "$RES/loadcell/ens45"
  cp "$R/lc45_study/summary.csv" "$RES/loadcell/ens45/" 2>/dev/null
  (cd "$R/lc45_study" && tar czf "$RES/loadcell/ens45/members.tgz" member_*/obstacle_forces.csv) 2>/dev/null
}

# The 64-member 5 mm column (fp32; fp64 with the split off) under the CUDA fast-path options.
part_ensemble_options() {
  local o t c="--set grid.h=0.005 --set time.dt=5e-5"
  for o in "" "--g2p-split off" "--g2p-split on --g2p-regcap on" "--sort 8" "--sort 0 --p2g atomic" "--g2p-block 64" \
           "--graph-steps 8"; do
    # shellcheck disable=SC2086
    t=${o:-default}
    ens "col5_64_fp32${t// /}" 120 "$COL" "$SC/ensembles/column_bench_64.toml" $c --precision fp32 $o
  done
  for o in "" "--g2p-split off"; do
    # shellcheck disable=SC2086
    t=${o:-default}
    ens "col5_64_fp64${t// /}" 120 "$COL" "$SC/ensembles/column_bench_64.toml" $c --precision fp64 $o
  done
}

# What the ensemble's time per step is made of: the 64-member 5 mm column sampled every 50 ms
# instead of 1 ms; the 1 mm member 0 of the 16-member ensemble alone, twice (run-to-run spread).
part_ensemble_diag() {
  ens col5_64_fp32_sparse 120 "$COL" "$SC/ensembles/column_bench_64.toml" --set grid.h=0.005 --set time.dt=5e-5 \
    --set output.series_dt=0.05 --precision fp32
  local k
  for k in a b; do
    run "col1_fp32_m0_$k" 60 "$COL" --precision fp32 --set frictional.phi_c_deg=21.312444480854175 \
      --set material.e0=0.9690217603212233
  done
}

# The scene calibration against Bui et al.'s deposit (data/calibration/bui_column.toml, 5 mm), then
# the 1 mm column with the fitted set and with the start set (their final profiles in $RES).
part_calibrate() {
  local t0=$SECONDS
  x 420 "$R/bui.txt" "$G" calibrate data/calibration/bui_column.toml --out "$R/bui_fit" --force --no-plot
  echo "  bui_column calibration: exit $?, $((SECONDS - t0)) s" | tee -a "$log"
  sed -n '/^parameter /,/^$/p; /^curve /,/^$/p; /^ iteration/,/^$/p; /^posterior over/,/^best final/p' "$R/bui.txt"
  rm -rf "$RES/bui_fit" && cp -r "$R/bui_fit" "$RES/bui_fit"
  run bui_fit_1mm 60 "$COL" --params "$R/bui_fit/bui_column.toml"
  run bui_start_1mm 60 "$COL"
  cp "$R/bui_fit_1mm/profile_final.csv" "$RES/bui_fit_1mm_profile.csv"
  cp "$R/bui_start_1mm/profile_final.csv" "$RES/bui_start_1mm_profile.csv"
}

# The batched rows of the ensemble part only (the sequential runs are those of part_ensemble),
# with the 5 mm fp32 run sampled every 50 ms beside them (the steps' share); ENS_1MM=0 leaves out
# the 1 mm ensemble.
part_ensemble_batched() {
  local p
  for p in fp32 fp64; do
    ens "col5_64_$p" 300 "$COL" "$SC/ensembles/column_bench_64.toml" --set grid.h=0.005 --set time.dt=5e-5 --precision $p
    grep -h "^device time" "$R/col5_64_$p.txt"
  done
  ens col5_64_fp32_sparse 120 "$COL" "$SC/ensembles/column_bench_64.toml" --set grid.h=0.005 --set time.dt=5e-5 \
    --set output.series_dt=0.05 --precision fp32
  grep -h "^device time" "$R/col5_64_fp32_sparse.txt"
  [ "${ENS_1MM:-1}" = 0 ] || ens col1_16_fp32 300 "$COL" "$SC/ensembles/column_bench_16.toml" --precision fp32
}

part_profile() {
  local ncu
  ncu=$(command -v ncu || ls /usr/local/cuda*/bin/ncu /opt/nvidia/nsight-compute/*/ncu 2>/dev/null | head -1)
  [ -n "$ncu" ] || { echo "ncu not found: profile skipped" | tee -a "$log"; return 0; }
  x 300 "$R/ncu_column.txt" "$ncu" --clock-control none --launch-skip 60 --launch-count 3 --section SpeedOfLight \
    --section LaunchStats --section Occupancy --section MemoryWorkloadAnalysis \
    "$G" bench mpm "$COL" --backend "$BACKEND" --steps 5 --warmup 60
  cp "$R/ncu_column.txt" "$RES/ncu_column.txt"
  grep -E "^  [a-z_]+kernel|Duration|Compute \(SM\) Throughput|Memory Throughput|Registers Per|Achieved Occupancy|Theoretical Occupancy" \
    "$R/ncu_column.txt" | head -40
}

part_profile_ensemble() {
  local ncu
  ncu=$(command -v ncu || ls /usr/local/cuda*/bin/ncu /opt/nvidia/nsight-compute/*/ncu 2>/dev/null | head -1)
  [ -n "$ncu" ] || { echo "ncu not found: profile skipped" | tee -a "$log"; return 0; }
  x 300 "$R/ncu_ensemble.txt" "$ncu" --clock-control none -k regex:"p2g_kernel|grid_kernel|g2p" --launch-skip 30000 \
    --launch-count 4 --section SpeedOfLight --section LaunchStats --section Occupancy --section MemoryWorkloadAnalysis \
    "$G" ensemble "$COL" "$SC/ensembles/column_bench_64.toml" --set grid.h=0.005 --set time.dt=5e-5 --precision fp32 \
    --backend "$BACKEND" --out "$R/ens" --force --no-png --quiet
  cp "$R/ncu_ensemble.txt" "$RES/ncu_ensemble.txt"
  grep -E "^  [a-z_]+.*kernel|Duration|Compute \(SM\) Throughput|Memory Throughput|Registers Per|Achieved Occupancy|Theoretical Occupancy|Local" \
    "$R/ncu_ensemble.txt" | head -60
}

part_sanitize_ensemble() {
  local cs tool rc failed=0
  cs=$(command -v compute-sanitizer || ls /usr/local/cuda*/bin/compute-sanitizer 2>/dev/null | head -1)
  [ -n "$cs" ] || { echo "compute-sanitizer not found" | tee -a "$log"; return 1; }
  for tool in memcheck racecheck synccheck; do
    x 200 "$R/san_ens_$tool.txt" "$cs" --tool $tool --error-exitcode 9 "$G" ensemble "$SC/column_collapse_ci.toml" \
      "$SC/ensembles/column_phi_lhs.toml" --backend "$BACKEND" --out "$R/san_ens" --force --no-png --quiet \
      --set 'stage[0].duration=0.02' --set 'stage[1].duration=0.05' --set 'output.times=[0.04]' --set output.series_dt=0.002
    rc=$?
    [ $rc -eq 0 ] || failed=1
    echo "  $tool ensemble of 8: exit $rc | $(grep -E 'ERROR SUMMARY|RACECHECK SUMMARY|SYNCCHECK SUMMARY' "$R/san_ens_$tool.txt" | head -1)" |
      tee -a "$log"
  done
  return $failed
}

part_sanitize() {
  local cs
  cs=$(command -v compute-sanitizer || ls /usr/local/cuda*/bin/compute-sanitizer 2>/dev/null | head -1)
  [ -n "$cs" ] || { echo "compute-sanitizer not found" | tee -a "$log"; return 1; }
  local ci=$SC/column_collapse_ci.toml cfg label args scene tool rc failed=0
  for cfg in "default|$ci|" "default|$SC/column_collapse_ci_frictional.toml|" \
             "volumetric averaging|$ci|--set solver.volumetric_averaging=true" "default|$SC/flume_ci.toml|" \
             "sort+tile|$ci|--sort 8 --p2g tile" "sort+tile|$SC/flume_ci.toml|--sort 8 --p2g tile" \
             "sort+warp, no graphs|$ci|--sort 8 --p2g warp --graphs off" \
             "sort+warp, no graphs|$SC/flume_ci.toml|--sort 8 --p2g warp --graphs off" "split G2P|$ci|--g2p-split on" \
             "Coulomb floor mu 0.4|$ci|--set wall[2].type=frictional --set wall[2].mu=0.4"; do
    IFS='|' read -r label scene args <<<"$cfg"
    for tool in ${SANITIZE_TOOLS:-memcheck racecheck}; do
      # shellcheck disable=SC2086  # args are words
      x 150 "$R/san.txt" "$cs" --tool $tool --error-exitcode 9 "$G" mpm "$scene" --backend "$BACKEND" $args \
        --stop-after 0.07 --out "$R/san" --force --no-png --quiet
      rc=$?
      [ $rc -eq 0 ] || failed=1
      echo "  $tool $label $(basename "$scene"): exit $rc | $(grep -E 'ERROR SUMMARY|RACECHECK SUMMARY' "$R/san.txt" | head -1)" |
        tee -a "$log"
    done
  done
  return $failed
}

part_3d() {
  local p opts c="--steps 30 --warmup 5 --split 20"
  echo "== 3D slab, 8e6 points (mpm/scenes/column_collapse_3d.toml)"
  for p in fp64 mixed fp32; do bench "3D slab $p" 200 "$SC/column_collapse_3d.toml" $c --precision $p; done
  for opts in "--g2p-split on" "--g2p-split on --g2p-regcap on" "--p2g tile" "--sort 0 --p2g atomic"; do
    # shellcheck disable=SC2086
    bench "3D slab fp32 $opts" 200 "$SC/column_collapse_3d.toml" $c --precision fp32 $opts
  done
  bench "3D slab fp64 --g2p-split on" 200 "$SC/column_collapse_3d.toml" $c --precision fp64 --g2p-split on
  grep -h "memory:" "$R"/bench_3D_slab_*.txt | sort -u
}

# One scene over the GPUs of a host (needs 2 GPUs; docs/mpm_slabs.md): the split's checks, the
# 3D slab's strong scaling (whole runs, 2 then 1 GPU) and the slab widened to 6.4e7 points.
part_slabs() {
  local n t0 wide=(--set 'grid.size=[0.60,0.15,0.40]' --set 'body[0].max=[0.20,0.10,0.40]')
  x 200 "$R/check_slabs.txt" "$B/mpm_cuda_check" --slabs --short || echo "  (slab checks failed, see $R/check_slabs.txt)"
  grep -o "[0-9]* slabs: .*" "$R/check_slabs.txt"
  for n in 2 1; do
    t0=$SECONDS
    run "slab3d_${n}gpu" 300 "$SC/column_collapse_3d.toml" --precision fp32 --stop-after 0.15 --devices $n
    echo "  3D slab on $n GPU(s): whole command $((SECONDS - t0)) s"
  done
  for n in 2 1; do
    t0=$SECONDS
    bench "slab3d 6.4e7 $n GPU" 300 "$SC/column_collapse_3d.toml" --precision fp32 "${wide[@]}" --steps 60 --warmup 5 \
      --devices $n
    echo "  6.4e7 points on $n GPU(s): whole command $((SECONDS - t0)) s"
  done
}

# One line: the whole command's seconds, the run's wall, the device time of its spans (steps x
# us per step) and what is left outside the steps (set-up, frames, samples, teardown).
host_time_figures() {
  awk -v l="$1" -v whole="$2" '/^steps:/ {n = $2} /^wall:/ {w = $2} /device time per step \(spans\)/ {d = $6}
    /^final run-out:/ {r = $3}
    END {dev = n * d * 1e-6; printf "  %-8s whole %.1f s, run wall %.1f s, device %.1f s (%s us/step x %s steps), outside the steps %.1f s, run-out %s m\n",
                                  l, whole, w, dev, d, n, whole - dev, r}' "$3"
}

part_frames() {
  local label g sc t0 t1
  for label in before after; do
    if [ $label = before ]; then g=${BASE_G:-} sc=${BASE_SC:-$SC}; else g=$G sc=$SC; fi
    [ -n "$g" ] || continue
    rm -rf "$R/slab3d_$label"
    t0=$(date +%s.%N)
    x 400 "$R/slab3d_$label.txt" "$g" mpm "$sc/column_collapse_3d.toml" --backend cuda --precision fp32 \
      --stop-after 0.15 --no-png --out "$R/slab3d_$label" --force
    t1=$(date +%s.%N)
    host_time_figures "$label" "$(awk -v a="$t0" -v b="$t1" 'BEGIN {print b - a}')" "$R/slab3d_$label.txt" | tee -a "$log"
    du -sh "$R/slab3d_$label" | tee -a "$log"
  done
}

main() {
  if [ $# -eq 0 ]; then
    sed -n '2,/^set -o/p' "${BASH_SOURCE[0]}" | sed '$d' | sed 's/^# \{0,1\}//'
    return 2
  fi
  local part fn f t0 status=0
  for part in "$@"; do
    case $part in
      build | check | paper | series | series-column | series-flume | series-fine | perf | profile | sanitize | 3d | ensemble | ensemble-batched | ensemble-diag | study | calibrate | profile-ensemble | ensemble-options | flow | sanitize-ensemble | loadcell-pt | loadcell-fr | loadcell-ens | slabs | frames | cylinder | series-3d | meshformats) ;;
      *) echo "unknown part '$part' (build check paper series series-column series-flume series-fine perf profile sanitize 3d ensemble ensemble-batched ensemble-diag study calibrate profile-ensemble ensemble-options flow sanitize-ensemble loadcell-pt loadcell-fr loadcell-ens slabs frames cylinder series-3d meshformats)" >&2
         return 2 ;;
    esac
  done
  mkdir -p "$RES" "$RUNS" || return 1
  for part in "$@"; do
    case $part in
      series) fn="part_series_column part_series_flume part_series_fine" ;;
      *) fn=part_${part//-/_} ;;
    esac
    local need_check=0  # the parts that run mpm_cuda_check (a prebuilt granflow serves the others)
    case $part in check | sanitize* | slabs) need_check=1 ;; esac
    if [ "$part" != build ] && { [ ! -x "$G" ] || { [ $need_check = 1 ] && [ ! -x "$B/mpm_cuda_check" ]; }; }; then
      log=$RES/build.log R=$RUNS/build
      mkdir -p "$R"
      part_build || return 1
    fi
    log=$RES/$part.log R=$RUNS/$part
    mkdir -p "$R"
    echo "== $part ($(date -u '+%Y-%m-%d %H:%M:%S UTC'), $(git rev-parse --short HEAD 2>/dev/null || echo 'no git'))" | tee -a "$log"
    t0=$SECONDS
    for f in $fn; do $f || status=1; done
    echo "== $part: $((SECONDS - t0)) s" | tee -a "$log"
    (cd "$R" && find . -name "*.csv" -o -name deposit_thickness.asc | tar czf "$RES/${part}_csv.tgz" -T - 2>/dev/null)
  done
  return $status
}

if [ "${BASH_SOURCE[0]}" = "$0" ]; then
  main "$@"
  exit $?
fi
