#!/usr/bin/env bash
# ctest package_install: cmake --install into a temporary prefix, then
#   1. no installed file (binaries included) holds the source or the build folder's path;
#   2. the installed granflow runs element and figures from an empty folder (data and plot
#      scripts found from the program's own folder);
#   3. a small project (consumer/) configures, builds and runs against the package.
#   check_install.sh CMAKE SOURCE_DIR BUILD_DIR CXX_COMPILER [PATH_CHECK=ON]
# PATH_CHECK OFF (debug-info and sanitizer builds, which embed source locations) skips 1.
set -euo pipefail
cmake=$1 src=$2 build=$3 cxx=$4 path_check=${5:-ON}
tmp=$(mktemp -d "${TMPDIR:-/tmp}/granflow_pkg.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
P=$tmp/prefix
fail() { echo "package_install: FAIL: $*" >&2; exit 1; }

SECONDS=0
"$cmake" --install "$build" --prefix "$P" >"$tmp/install.log" || { cat "$tmp/install.log"; fail "cmake --install"; }
[ -x "$P/bin/granflow" ] || fail "no $P/bin/granflow"
for f in share/granflow/data/params/element_test.toml share/granflow/data/tests/fig4_e080.toml \
         share/granflow/data/calibration/kfs_fit.toml share/granflow/data/lab/kfsdb/OE2.csv \
         share/granflow/mpm/scenes/column_collapse_ci.toml share/granflow/scripts/plot_figures.py \
         include/granflow/constitutive.hpp include/granflow/umat.h lib/cmake/granflow/granflowConfig.cmake \
         lib/cmake/granflow/granflowConfigVersion.cmake; do
  [ -e "$P/$f" ] || fail "not installed: $f"
done
echo "installed $(find "$P" -type f | wc -l) files after ${SECONDS} s"

# 1. no source or build path (the build folder may lie outside the source tree)
if [ "$path_check" = ON ]; then
  for dir in "$src" "$build"; do
    hits=$(grep -rlF -- "$dir" "$P" || true)
    [ -z "$hits" ] || fail "installed files hold the path $dir: $hits"
  done
  echo "no installed file holds $src or $build"
else
  echo "path check skipped: a debug-info or sanitizer build embeds source locations on purpose"
fi

# 2. the installed program from an empty folder, without GRANFLOW_DATA_DIR
run=$tmp/empty
mkdir "$run"
cd "$run"
unset GRANFLOW_DATA_DIR
"$P/bin/granflow" element >element.txt 2>&1 || { cat element.txt; fail "granflow element"; }
grep -q "right-hand-side evaluations" element.txt || fail "granflow element printed no run summary"
"$P/bin/granflow" element "$P/share/granflow/data/tests/fig4_e080.toml" --out fig4.csv >/dev/null 2>&1 ||
  fail "granflow element fig4_e080.toml"
[ "$(wc -l <fig4.csv)" -eq 32 ] || fail "fig4.csv: $(wc -l <fig4.csv) lines, expected 32"
"$P/bin/granflow" figures --out figs >figures.txt 2>&1 || { cat figures.txt; fail "granflow figures"; }
[ -s figs/fig6.csv ] || fail "granflow figures wrote no figs/fig6.csv"
! grep -q "not found" figures.txt || { cat figures.txt; fail "granflow figures did not find its plot script"; }
if python3 -c 'import matplotlib' 2>/dev/null || /usr/bin/python3 -c 'import matplotlib' 2>/dev/null; then
  [ -s figs/fig6.png ] || { cat figures.txt; fail "matplotlib present but no figs/fig6.png"; }
fi
echo "installed granflow: element and figures ran from an empty folder ($(ls figs | wc -l) files)"
[ -z "$(ls -A "$run" | grep -v -e '^element.txt$' -e '^fig4.csv$' -e '^figures.txt$' -e '^figs$')" ] ||
  fail "the program wrote outside its outputs: $(ls -A "$run")"

# 3. a consumer project against the package
"$cmake" -S "$src/tests/package/consumer" -B "$tmp/consumer" -DCMAKE_PREFIX_PATH="$P" -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_CXX_COMPILER="$cxx" >"$tmp/consumer.log" 2>&1 || { cat "$tmp/consumer.log"; fail "consumer: configure"; }
"$cmake" --build "$tmp/consumer" >>"$tmp/consumer.log" 2>&1 || { cat "$tmp/consumer.log"; fail "consumer: build"; }
GRANFLOW_DATA_DIR=$P/share/granflow/data "$tmp/consumer/consumer" || fail "consumer: run"
echo "package_install: OK (${SECONDS} s)"
