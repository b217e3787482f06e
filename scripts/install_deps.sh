#!/usr/bin/env bash
# Installs the Debian packages granflow needs (no other network access is used).
# CUDA (nvcc) is optional: when /usr/local/cuda/bin/nvcc exists the CUDA targets are built too.
set -euo pipefail
packages=(build-essential cmake libeigen3-dev libsundials-dev libnlopt-cxx-dev libgtest-dev libfccp-dev
          libcli11-dev libtomlplusplus-dev python3 python3-matplotlib
          clang libclang-rt-dev  # clang + libFuzzer: scripts/fuzz.sh
          gfortran)              # the UMAT's Fortran calling-convention test (tests/umat)
packages+=(pybind11-dev python3-dev python3-numpy python3-pytest)  # Python module: docs/python.md
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
