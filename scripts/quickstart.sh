#!/usr/bin/env bash
# Set-up to result: install the program's packages, build the program, run the default example jobs.
# Only build/granflow is built (no tests, no Python module); CUDA only where a GPU is present.
# scripts/test.sh later in the same build/ turns the tests and the rest on.
set -euo pipefail
cd "$(dirname "$0")/.."
# OpenMP threads that spin at each barrier make the small MPM example 10x slower on a loaded
# machine (114 s instead of 11 s at load 7 on 2 cores); sleeping costs little on an idle one.
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
t=$SECONDS
took() {  # took WHAT: the wall time since the last call (docs/install.md, "Time to a first result")
  echo "== quickstart: $1 took $((SECONDS - t)) s"
  t=$SECONDS
}
scripts/install_deps.sh
took "packages"
t_build=$SECONDS
# A build/ configured before (e.g. by scripts/test.sh) keeps its options: only the program is built.
opts=() what="existing build/ options"
if [ ! -f build/CMakeCache.txt ]; then
  cuda=OFF
  if nvidia-smi -L >/dev/null 2>&1; then cuda=ON; fi
  opts=(-DGRANFLOW_TESTS=OFF -DGRANFLOW_CUDA=$cuda -DCMAKE_UNITY_BUILD=ON) what="tests off, CUDA $cuda, unity build"
fi
scripts/build.sh --target granflow "${opts[@]}"
took "build ($what)"
echo
echo "== granflow element: undrained simple shear, paper's element-test set (Fig. 6 protocol) =="
./build/granflow element
took "element"
echo
echo "== granflow figures: the paper's element tests (Figs. 4-7) and the DEM comparison =="
./build/granflow figures --out out/figures
took "figures"
echo
echo "== granflow calibrate: collisional parameters fitted to the DEM steady-shear data =="
./build/granflow calibrate data/calibration/dem_collisional_mu0.toml --out out/dem_mu0_fit --force
./build/granflow element data/tests/fig6_e099.toml --params out/dem_mu0_fit/dem_mu0.toml --out out/fig6_fitted.csv --force
took "calibrate"
echo
echo "== granflow mpm: small column collapse (10 mm grid) on the CPU twin =="
./build/granflow mpm mpm/scenes/column_collapse_ci.toml --out out/column_ci --force
took "mpm"
echo "== quickstart: build and examples took $((SECONDS - t_build)) s"
