#!/usr/bin/env bash
# Runs the shipped CPU examples with a built granflow and lists the SHA-256 of every result file
# (element CSVs, figure CSVs, MPM series, final profiles and VTU frames, an ensemble's summaries
# and a calibration's fitted curves). Two trees whose lists
# match produce byte-identical results: the check for refactors that must not change a number.
#   scripts/reference_outputs.sh [BUILD_DIR] [OUT_DIR]   (defaults: build, out/reference)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
out=${2:-out/reference}
g="$build/granflow"
rm -rf "$out"
mkdir -p "$out/element"
"$g" element --out "$out/element/default.csv" >/dev/null
for t in data/tests/*.toml; do
  "$g" element "$t" --out "$out/element/$(basename "$t" .toml).csv" >/dev/null
done
"$g" figures --out "$out/figures" >/dev/null
for s in mpm/scenes/*_ci*.toml; do
  "$g" mpm "$s" --out "$out/mpm/$(basename "$s" .toml)" --no-png --quiet >/dev/null
done
"$g" ensemble mpm/scenes/column_collapse_ci.toml mpm/scenes/ensembles/column_phi_lhs.toml \
     --out "$out/ensemble/column_phi_lhs" --no-png --quiet >/dev/null
# the summary's wall_s column is a timing: hashed without it
awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == "wall_s") w = i }
         { out = ""; n = 0; for (i = 1; i <= NF; ++i) if (i != w) out = out (n++ ? "," : "") $i; print out }' \
    "$out/ensemble/column_phi_lhs/summary.csv" > "$out/ensemble/column_phi_lhs/summary_untimed.csv"
rm "$out/ensemble/column_phi_lhs/summary.csv"
"$g" calibrate data/calibration/frictional_synthetic.toml --out "$out/calibration/frictional_synthetic" >/dev/null
(cd "$out" && find . -type f \( -name '*.csv' -o -name '*.vtu' -o -name '*.pvd' \) | LC_ALL=C sort | xargs sha256sum)
