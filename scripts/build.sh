#!/usr/bin/env bash
# Configures and builds granflow in build/ (Release). Extra arguments go to CMake's configure step;
# a leading `--target NAME` builds only that target (scripts/quickstart.sh: the program alone).
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc 2>/dev/null || echo 2)
target=()
if [ "${1:-}" = "--target" ]; then
  target=(--target "$2")
  shift 2
fi
source scripts/generator.sh
cmake -S . -B build $(cmake_generator build) -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
cmake --build build -j"$jobs" "${target[@]}"
