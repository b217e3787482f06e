#!/usr/bin/env bash
# compute-sanitizer memcheck and racecheck of the CUDA backend on small scenes (GPU machine,
# repository root, $OUT set): default path, and sorting with the tile and warp P2G.
set -o pipefail
(time scripts/gpu_build.sh) 2>&1 | grep real
CS=$(command -v compute-sanitizer || ls /usr/local/cuda*/bin/compute-sanitizer | head -1)
for cfg in "default|" "sort+tile|--sort 8 --p2g tile" "sort+warp|--sort 8 --p2g warp --graphs off"; do
  label=${cfg%%|*}; args=${cfg#*|}
  for scene in mpm/scenes/column_collapse_ci.toml mpm/scenes/flume_ci.toml; do
    for tool in memcheck racecheck; do
      timeout 150 $CS --tool $tool --error-exitcode 9 build-gpu/granflow mpm $scene --backend cuda $args \
        --stop-after 0.07 --out /tmp/san --force --no-png --quiet > /tmp/san.log 2>&1
      echo "$tool $label $(basename $scene): exit $? | $(grep -E 'ERROR SUMMARY|RACECHECK SUMMARY' /tmp/san.log | head -1)"
    done
  done
done
