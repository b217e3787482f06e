#!/usr/bin/env bash
# Copies the header-only dependencies into .deps/include (git-ignored) for the GPU machine.
# assimp is not carried: the GPU-only build has no mesh reader (mesh keys refused, naming
# libassimp-dev); mesh obstacles reach the kernels as held nodes made on the host (mpm_meshes.md).
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p .deps/include
cp -r /usr/include/eigen3/Eigen /usr/include/eigen3/unsupported /usr/include/toml++ /usr/include/CLI \
      /usr/include/libfccp .deps/include/
du -sh .deps
