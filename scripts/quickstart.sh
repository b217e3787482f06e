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
echo
echo "== granflow calibrate: collisional parameters fitted to the DEM steady-shear data =="
./build/granflow calibrate data/calibration/dem_collisional_mu0.toml --out out/dem_mu0_fit --force
./build/granflow element data/tests/fig6_e099.toml --params out/dem_mu0_fit/dem_mu0.toml --out out/fig6_fitted.csv --force
echo
echo "== granflow mpm: small column collapse (10 mm grid) on the CPU twin =="
./build/granflow mpm mpm/scenes/column_collapse_ci.toml --out out/column_ci --force
