#!/usr/bin/env bash
# Copies what the GPU machine's build needs and lacks (it has CMake and nvcc only) into .deps
# (git-ignored): the header-only dependencies into .deps/include, and, where assimp is installed,
# its headers and the shared libraries it loads (libassimp, libdraco, libminizip, libz: about
# 13 MB) into .deps/lib, so that the GPU build reads STL, OBJ and PLY meshes (mpm_meshes.md).
# Without assimp here the GPU build has no mesh reader and refuses mesh keys, naming libassimp-dev.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p .deps/include
cp -r /usr/include/eigen3/Eigen /usr/include/eigen3/unsupported /usr/include/toml++ /usr/include/CLI \
      /usr/include/libfccp .deps/include/
lib=/usr/lib/x86_64-linux-gnu
rm -rf .deps/lib .deps/include/assimp  # no stale copy: the GPU build links what this run finds
if [ -f /usr/include/assimp/Importer.hpp ] && [ -f $lib/libassimp.so.5 ]; then
  mkdir -p .deps/lib
  cp -r /usr/include/assimp .deps/include/
  for so in libassimp.so.5 libdraco.so.7 libminizip.so.1 libz.so.1; do cp -L "$lib/$so" .deps/lib/; done
else
  echo "copy_deps: no assimp here (libassimp-dev): the GPU build will refuse mesh keys" >&2
fi
du -sh .deps
