#!/usr/bin/env bash
# Sourced by the build scripts: cmake_generator DIR prints -GNinja when DIR is not configured yet
# and ninja is installed (Debian ninja-build), else nothing (an existing folder keeps its
# generator). Ninja starts a target's objects as soon as their sources are ready, where Make's
# targets wait for the libraries they link: the 2-core CI build keeps both cores busy
# (docs/reliability_ci.md).
cmake_generator() {
  if [ ! -f "$1/CMakeCache.txt" ] && command -v ninja >/dev/null 2>&1; then echo -GNinja; fi
}

# fast_linker: prints -DGRANFLOW_LLD=ON where LLVM's lld is installed (Debian lld, which
# scripts/install_deps.sh --tests installs): C++ links about 3x faster (docs/reliability_ci.md).
fast_linker() {
  if command -v ld.lld >/dev/null 2>&1; then echo -DGRANFLOW_LLD=ON; fi
}
