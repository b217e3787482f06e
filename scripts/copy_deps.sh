#!/usr/bin/env bash
# Copies the header-only dependencies into .deps/include (git-ignored) for the GPU machine.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p .deps/include
cp -r /usr/include/eigen3/Eigen /usr/include/eigen3/unsupported /usr/include/toml++ /usr/include/CLI \
      /usr/include/libfccp .deps/include/
du -sh .deps
