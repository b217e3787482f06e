#!/usr/bin/env bash
# Set-up to result: install, build, and run the default example jobs.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install_deps.sh
scripts/build.sh
echo
echo "== granflow element: undrained simple shear, paper's element-test set (Fig. 6 protocol) =="
./build/granflow element
echo
echo "== granflow figures: the paper's element tests (Figs. 4-7) and the DEM comparison =="
./build/granflow figures --out out/figures
