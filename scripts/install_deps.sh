#!/usr/bin/env bash
# Installs the Debian packages granflow needs (no other network access is used).
#   scripts/install_deps.sh          the program and its example jobs (scripts/quickstart.sh)
#   scripts/install_deps.sh --tests  the above plus what the tests need (scripts/test.sh, .ci/run)
# CUDA (nvcc) is optional: when /usr/local/cuda/bin/nvcc exists the CUDA targets are built too.
set -euo pipefail
tests=0
case "${1:-}" in
  "") ;;
  --tests) tests=1 ;;
  *) echo "usage: $0 [--tests]" >&2; exit 2 ;;
esac
# The program: compilers, CMake, the libraries it links, and python3 + matplotlib for the PNGs
# that figures, calibrate and mpm write beside their CSVs.
packages=(build-essential cmake ninja-build libeigen3-dev libsundials-dev libnlopt-cxx-dev libfccp-dev
          libcli11-dev libtomlplusplus-dev python3 python3-matplotlib)
if [ "$tests" -eq 1 ]; then
  packages+=(libgtest-dev
             clang libclang-rt-dev  # clang + libFuzzer: scripts/fuzz.sh
             lld                    # the test builds link with it (GRANFLOW_LLD, scripts/generator.sh)
             gfortran)              # the UMAT's Fortran calling-convention test (tests/umat)
  packages+=(pybind11-dev python3-dev python3-numpy python3-pytest)  # Python module: docs/python.md
  # optional MPI: ensembles and calibration over ranks (docs/mpm_ensembles.md); libsundials-dev
  # already pulls in libopenmpi-dev and gfortran, they are named for what the tests use
  packages+=(libopenmpi-dev openmpi-bin)
  packages+=(libgdal-dev)  # optional: GeoTIFF and other terrain rasters through GDAL (docs/mpm_terrain.md)
  packages+=(libassimp-dev)  # optional: STL, OBJ and PLY meshes through assimp (docs/mpm_meshes.md)
  packages+=(python3-vtk9)  # test dependency: VTK's reader on the frames (tests/mpm/read_frame_vtk.py)
fi
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "granflow: all Debian packages present"
  exit 0
fi
echo "granflow: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
