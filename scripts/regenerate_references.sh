#!/usr/bin/env bash
# Rebuilds the shipped references that a CPU makes in minutes, into their repository paths, so
# that `git diff` shows what moved; --check compares instead and writes nothing.
#
#   scripts/regenerate_references.sh [--check] [--build DIR] [NAME...]
#
# NAME (default: all but series-2.5mm), with its time measured on the project's 2-core machine,
# shared with other builds (the longer time: under a load of 5-9), 2026-12-02; the default set
# took 6.3 min with --check:
#   figures        2-3 s   granflow figures (6 s with the PNGs): docs/figures/fig4-7, fig6_sweep, fig7_fixed_strain,
#                          dem_comparison, dem_errors (CSV + PNG)
#   dem-joint      0.3-1 s granflow calibrate data/calibration/dem_collisional_joint.toml: V_sd, V_m,
#                          V_sd_inf, mu_star of data/params/column_collapse_flow.toml
#   kfs            20-47 s granflow calibrate data/calibration/kfs_fit.toml: data/params/kfs_fitted.toml,
#                          docs/figures/kfs_tests.csv, kfs_identifiability.csv, kfs_*.png
#   kfs-shipped    3-6 s   --check only: the shipped set evaluated by kfs_fit.toml (--evaluate) gives the
#                          shipped fit's misfit (1e-5: the printed digits) and docs/figures/kfs_tests.csv
#   kfs-undrained  30-52 s granflow calibrate data/calibration/kfs_undrained_e0.toml (the shipped set
#                          fixed): docs/figures/kfs_undrained_e0_tests.csv, kfs_undrained_*.png
#   hashes         2.4-3.8 min  scripts/reference_outputs.sh: docs/checks/reference_outputs.sha256
#   series         1.5-3 min  the column mesh series on the CPU twin at 10 and 5 mm (fp64,
#                          dt with h, one OpenMP thread unless OMP_NUM_THREADS says otherwise):
#                          their rows of docs/figures/mpm_column_mesh_series.csv (+ PNG)
#   series-2.5mm   16 min  the 2.5 mm row the same way (975 s; not in the default set)
# The 1 mm row of the series and every table of docs/benchmarks.md are GPU-made: they name the
# commit they were measured at and are not rebuilt here (docs/benchmarks.md, "Measured at").
#
# Tolerances of --check (scripts/compare_references.py), and why:
#   figures: 1e-5 x each column's largest |value|. CVODE runs at rtol 1e-6; another compiler or
#     libm may take other steps, which moves a curve by about rtol, while a change of the law or
#     the driver that matters moves it by far more.
#   kfs, kfs-undrained: the fitted values and the per-test errors to 1e-6 relative: the fit is
#     bitwise the same for any thread count (docs/calibration.md), so only printing rounds; on
#     another compiler BOBYQA's path may fork after ~1000 evaluations (then regenerate there).
#   kfs-shipped: misfit 1e-5 relative (6 digits in the set's source line); per-test table 1e-5 of
#     each column's largest value (the per-test e0, read back with 12 digits, move CVODE's steps:
#     the undrained rows by ~1e-6).
#   dem-joint: 1e-9 relative (the same binary gives the same fit; 17 digits in the file).
#   hashes: identical (the refactor check of docs/reliability_ci.md; machine-specific).
#   series: run-out and height to 1e-4 m (the CPU twin is deterministic; 1e-4 m is the printed
#     precision of the table).
# ctest -R References runs `--check` of figures, dem-joint and kfs-shipped (tests/references/).
set -euo pipefail
cd "$(dirname "$0")/.."
check=0
build=build
names=()
while [ $# -gt 0 ]; do
  case $1 in
    --check) check=1 ;;
    --build) build=$2; shift ;;
    -h | --help) sed -n '2,/^set -euo/p' "$0" | sed '$d'; exit 0 ;;
    *) names+=("$1") ;;
  esac
  shift
done
[ ${#names[@]} -gt 0 ] || names=(figures dem-joint kfs kfs-undrained hashes series)
G=${GRANFLOW:-$build/granflow}
[ -x "$G" ] || { echo "no $G: build granflow first (or set GRANFLOW)" >&2; exit 2; }
PY=${PYTHON:-python3}
tmp=$(mktemp -d "${TMPDIR:-/tmp}/granflow_refs.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
fail=0
commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
# a tree with edited sources is not "at" its commit (docs and data edits do not change a run)
[ -z "$(git status --porcelain --untracked-files=no -- constitutive elementtest calibration mpm io cli cmake \
  CMakeLists.txt 2>/dev/null)" ] || commit="$commit+edits"

# take SHIPPED FRESH MODE RTOL [KEY]: --check compares, else copies FRESH over SHIPPED.
take() {
  local shipped=$1 fresh=$2 mode=$3 rtol=$4
  shift 4
  if [ $check -eq 1 ]; then
    if [ ! -f "$shipped" ]; then
      echo "  $shipped: not shipped" >&2
      fail=1
    elif "$PY" scripts/compare_references.py "$mode" "$shipped" "$fresh" "$rtol" "$@"; then
      echo "  $shipped: matches (rtol $rtol)"
    else
      echo "  $shipped: DIFFERS from the current code (rtol $rtol): regenerate it in the same commit" >&2
      fail=1
    fi
  else
    cp "$fresh" "$shipped"
    echo "  wrote $shipped"
  fi
}
# png FRESH SHIPPED: pictures are copied when writing, never compared.
png() { [ $check -eq 1 ] || [ ! -f "$1" ] || cp "$1" "$2"; }

ref_figures() {
  "$G" figures --out "$tmp/fig" $([ $check -eq 1 ] && echo --no-png) >/dev/null
  for f in fig4 fig5 fig6 fig7 fig6_sweep fig7_fixed_strain dem_comparison dem_errors; do
    take "docs/figures/$f.csv" "$tmp/fig/$f.csv" csv 1e-5
  done
  for f in fig4 fig5 fig6 fig7 dem_comparison; do png "$tmp/fig/$f.png" "docs/figures/$f.png"; done
}

ref_kfs() {
  "$G" calibrate data/calibration/kfs_fit.toml --out "$tmp/kfs" --quiet $([ $check -eq 1 ] && echo --no-plot) \
    2>"$tmp/kfs.err" || { cat "$tmp/kfs.err" >&2; return 1; }
  take data/params/kfs_fitted.toml "$tmp/kfs/kfs_fitted.toml" text 1e-6
  take docs/figures/kfs_tests.csv "$tmp/kfs/tests.csv" csv 1e-6
  take docs/figures/kfs_identifiability.csv "$tmp/kfs/identifiability.csv" csv 1e-6
  for f in q_eps1 q_p epsv_eps1 e_logp; do png "$tmp/kfs/tests_$f.png" "docs/figures/kfs_$f.png"; done
}

# The shipped set evaluated by kfs_fit.toml (--evaluate: no fit, a few seconds): its misfit must be
# the shipped fit's and its per-test table the shipped one, so a change of the law, the driver or
# the misfit that would move the fit shows without running it. The per-test e0 come from the
# shipped kfs_identifiability.csv (12 digits).
ref_kfs_shipped() {
  local job=$tmp/kfs_shipped.toml
  awk -v root="$PWD" -v ids=docs/figures/kfs_identifiability.csv '
    BEGIN { FS = ","; while ((getline l < ids) > 0) { split(l, w, ","); if (w[1] ~ /^test.e0@/) e0[substr(w[1], 9)] = w[2] }; FS = " " }
    /^params = / { print "params = \"" root "/data/params/kfs_fitted.toml\""; next }
    /^data = "\.\.\// { sub(/"\.\.\//, "\"" root "/data/"); print; next }
    /^experiment = / && prev ~ /test.e0/ { print; n = $3; gsub(/"/, "", n); print "start = " e0[n]; prev = ""; next }
    { print; prev = $0 }' data/calibration/kfs_fit.toml >"$job"
  "$G" calibrate "$job" --evaluate --out "$tmp/kfse" --quiet --no-plot 2>"$tmp/kfse.err" ||
    { cat "$tmp/kfse.err" >&2; return 1; }
  local shipped fresh
  shipped=$(sed -n 's/^source = .*-> \([0-9.e+-]*\)).*/\1/p' data/params/kfs_fitted.toml)
  fresh=$(sed -n 's/^misfit: start \([0-9.e+-]*\) .*/\1/p' "$tmp/kfse/report.txt")
  if [ $check -eq 0 ]; then echo "  (nothing to write: the check of the shipped set only)"; return 0; fi
  if awk -v a="$shipped" -v b="$fresh" 'BEGIN { d = a - b; exit !(a > 0 && (d < 0 ? -d : d) <= 1e-5 * a) }'; then
    echo "  data/params/kfs_fitted.toml: re-evaluates to misfit $fresh (shipped $shipped, rtol 1e-5)"
  else
    echo "  data/params/kfs_fitted.toml: re-evaluates to misfit $fresh, shipped $shipped: regenerate (kfs) in the same commit" >&2
    fail=1
  fi
  # 1e-5: the e0 read back with 12 digits move CVODE's steps, and so the undrained rows, by ~1e-6
  take docs/figures/kfs_tests.csv "$tmp/kfse/tests.csv" csv 1e-5
}

# The collisional constants of data/params/column_collapse_flow.toml are the fit of
# dem_collisional_joint.toml (ten DEM groups, milliseconds); the rest of that file is by hand.
ref_dem_joint() {
  local set=data/params/column_collapse_flow.toml keys='^(V_sd|V_m|V_sd_inf|mu_star) = '
  "$G" calibrate data/calibration/dem_collisional_joint.toml --out "$tmp/dj" --quiet --no-plot \
    --no-cross-validation 2>"$tmp/dj.err" || { cat "$tmp/dj.err" >&2; return 1; }
  grep -E "$keys" "$tmp/dj/dem_joint.toml" >"$tmp/dj.fresh"
  sed -E 's/[[:space:]]*#.*//' "$set" | grep -E "$keys" >"$tmp/dj.shipped"
  if [ $check -eq 1 ]; then
    take_text_lines "$set" "$tmp/dj.shipped" "$tmp/dj.fresh"
  else
    awk 'NR == FNR { split($0, w, " = "); v[w[1]] = w[2]; next }
         { for (k in v) if (index($0, k " = ") == 1) { c = index($0, "#"); $0 = k " = " v[k] (c ? "      " substr($0, c) : "") } print }' \
      "$tmp/dj.fresh" "$set" >"$tmp/dj.toml"
    cp "$tmp/dj.toml" "$set"
    echo "  wrote V_sd, V_m, V_sd_inf, mu_star of $set"
  fi
}
# take_text_lines NAME SHIPPED FRESH: the check of a few key = value lines (1e-9 relative: the
# same binary gives the same fit; the file holds them with 17 digits).
take_text_lines() {
  if "$PY" scripts/compare_references.py text "$2" "$3" 1e-9; then echo "  $1: matches (rtol 1e-9)"; else
    echo "  $1: DIFFERS from the current code: regenerate it in the same commit" >&2
    fail=1
  fi
}

ref_kfs_undrained() {
  "$G" calibrate data/calibration/kfs_undrained_e0.toml --out "$tmp/kfsu" --quiet \
    $([ $check -eq 1 ] && echo --no-plot) 2>"$tmp/kfsu.err" || { cat "$tmp/kfsu.err" >&2; return 1; }
  take docs/figures/kfs_undrained_e0_tests.csv "$tmp/kfsu/tests.csv" csv 1e-6
  for f in q_p q_eps1; do png "$tmp/kfsu/tests_$f.png" "docs/figures/kfs_undrained_$f.png"; done
}

ref_hashes() {
  scripts/reference_outputs.sh "$build" "$tmp/reference" >"$tmp/reference.sha256"
  if [ $check -eq 1 ]; then
    if diff -u docs/checks/reference_outputs.sha256 "$tmp/reference.sha256" >&2; then
      echo "  docs/checks/reference_outputs.sha256: identical"
    else
      echo "  docs/checks/reference_outputs.sha256: DIFFERS (lines above)" >&2
      fail=1
    fi
  else
    cp "$tmp/reference.sha256" docs/checks/reference_outputs.sha256
    echo "  wrote docs/checks/reference_outputs.sha256 ($(wc -l <"$tmp/reference.sha256") files)"
  fi
}

# series_row H DT: one CPU-twin run of the column; its row (columns of the shipped CSV) in $tmp/row_H.
series_row() {
  local h=$1 dt=$2 mm t0 t1
  mm=$(awk -v h="$h" 'BEGIN {printf "%g", h * 1000}')
  t0=$(date +%s.%N)
  # one thread unless told: on a shared machine OpenMP barriers stall (docs/mpm.md); the result
  # does not depend on the thread count
  OMP_NUM_THREADS=${OMP_NUM_THREADS:-1} "$G" mpm mpm/scenes/column_collapse.toml --backend cpu --set "grid.h=$h" --set "time.dt=$dt" \
    --set output.series_dt=5e-3 --out "$tmp/col_$mm" --no-png --quiet >"$tmp/col_$mm.txt"
  t1=$(date +%s.%N)
  awk -F, -v mm="$mm" -v wall="$(awk -v a="$t0" -v b="$t1" 'BEGIN {printf "%.1f", b - a}')" -v c="$commit" \
    -v txt="$tmp/col_$mm.txt" 'BEGIN {
      while ((getline l < txt) > 0) {
        if (l ~ /^final run-out:/) { split(l, w, " "); r = w[3] }
        if (l ~ /^final height:/) { split(l, w, " "); ht = w[3] }
        if (l ~ /^particles:/) { split(l, w, " "); n = w[2] } }
      print mm "," n "," r "," ht "," c "," wall }' >"$tmp/row_$mm"
}

# The CPU rows replace theirs in the shipped CSV; errors against the 1 mm row are recomputed.
ref_series() {
  local csv=docs/figures/mpm_column_mesh_series.csv
  [ "$1" = all ] && series_row 0.01 1e-4 && series_row 0.005 5e-5
  [ "$1" = 2.5 ] && series_row 0.0025 2.5e-5
  cat "$tmp"/row_* >"$tmp/rows"
  awk -F, -v OFS=, -v rows="$tmp/rows" 'BEGIN { while ((getline l < rows) > 0) { split(l, w, ","); new[w[1]] = l } }
    /^#/ { print; next }
    !hdr { hdr = 1; for (i = 1; i <= NF; ++i) col[$i] = i; print; next }
    { line[++n] = $0 }
    END {
      for (k = 1; k <= n; ++k) { split(line[k], f, ","); if (f[1] == 1) { r1 = f[col["runout_m"]]; h1 = f[col["height_m"]] } }
      for (k = 1; k <= n; ++k) {
        m = split(line[k], f, ",")
        if (f[1] in new) {
          split(new[f[1]], w, ",")
          if (w[2] != "") f[col["points"]] = w[2]
          f[col["runout_m"]] = w[3]; f[col["height_m"]] = w[4]
          f[col["backend"]] = "cpu"; f[col["measured_at"]] = w[5]; f[col["wall_s"]] = w[6]
          f[col["device"]] = "2-core x86-64 (shared; 1 thread)"
        }
        if (f[1] != 1) {
          f[col["runout_error_vs_1mm"]] = sprintf("%.4f", f[col["runout_m"]] / r1 - 1)
          f[col["height_error_vs_1mm"]] = sprintf("%.4f", f[col["height_m"]] / h1 - 1)
        }
        out = f[1]; for (i = 2; i <= m; ++i) out = out "," f[i]; print out
      } }' "$csv" >"$tmp/series.csv"
  if [ $check -eq 1 ]; then
    local bad=0
    while IFS=, read -r mm _ r ht _; do
      awk -F, -v mm="$mm" -v r="$r" -v ht="$ht" 'BEGIN { bad = 1 }
        !/^#/ && $1 == mm { bad = ($3 - r > 1e-4 || r - $3 > 1e-4 || $4 - ht > 1e-4 || ht - $4 > 1e-4)
                             if (bad) printf "  %s: %s mm shipped run-out %s height %s, fresh %s %s\n", FILENAME, mm, $3, $4, r, ht > "/dev/stderr" }
        END { exit bad }' "$csv" || bad=1
    done <"$tmp/rows"
    if [ $bad -eq 0 ]; then echo "  $csv: CPU rows match (1e-4 m)"; else
      echo "  $csv: DIFFERS from the current code: regenerate it in the same commit" >&2
      fail=1
    fi
  else
    cp "$tmp/series.csv" "$csv"
    echo "  wrote the CPU rows of $csv"
    local p
    for p in "$PY" /usr/bin/python3; do  # a pyenv shim may lack matplotlib
      if "$p" -c 'import matplotlib' 2>/dev/null; then "$p" scripts/plot_mesh_series.py >/dev/null; break; fi
    done
  fi
}

for n in "${names[@]}"; do
  t0=$SECONDS
  echo "$n:"
  case $n in
    figures) ref_figures ;;
    kfs) ref_kfs ;;
    kfs-shipped) ref_kfs_shipped ;;
    dem-joint) ref_dem_joint ;;
    kfs-undrained) ref_kfs_undrained ;;
    hashes) ref_hashes ;;
    series) ref_series all ;;
    series-2.5mm) ref_series 2.5 ;;
    *) echo "unknown reference '$n' (figures dem-joint kfs kfs-shipped kfs-undrained hashes series series-2.5mm)" >&2; exit 2 ;;
  esac
  echo "  ($((SECONDS - t0)) s)"
done
[ $fail -eq 0 ] || { echo "some shipped references differ from the current code" >&2; exit 1; }
