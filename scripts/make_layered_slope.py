#!/usr/bin/env python3
"""Rasters of mpm/scenes/layered_slope_ci.toml (docs/mpm_terrain.md, "A layered slope").

A synthetic slope dipping 30 deg along x (easting) that levels out into a floor at x = 0.6 m,
and the tops of the two layers seeded on it: a weak layer 6 cm thick (three 20 mm cells) and a strong block 4 cm
above it, both over the plan x in [0.06, 0.22] m. ESRI ASCII grids of 1 cm cells, georeferenced
in UTM-like metres (xllcorner 600000, yllcorner 4500000, elevations about 200 m).
"""
import math
import os
import sys

WEST, SOUTH, CELL, NCOLS, NROWS = 600000.0 - 0.05, 4500000.0 - 0.05, 0.01, 100, 30
TOE, TAN = 0.6, math.tan(math.radians(30.0))


def ground(x):  # x: scene x (easting - 600000)
    return 200.0 + TAN * max(0.0, TOE - x)


def write(path, dz):
    with open(path, "w") as f:
        f.write(f"ncols {NCOLS}\nnrows {NROWS}\nxllcorner {WEST:.2f}\nyllcorner {SOUTH:.2f}\ncellsize {CELL}\n")
        for _ in range(NROWS):
            xs = [WEST + (c + 0.5) * CELL - 600000.0 for c in range(NCOLS)]
            f.write(" ".join(f"{ground(x) + dz:.6f}" for x in xs) + "\n")


out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "mpm", "scenes", "layered_slope")
os.makedirs(out, exist_ok=True)
write(os.path.join(out, "ground.asc"), 0.0)
write(os.path.join(out, "weak_top.asc"), 0.06)
write(os.path.join(out, "strong_top.asc"), 0.10)
