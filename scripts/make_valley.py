#!/usr/bin/env python3
"""Writes the synthetic valley of mpm/scenes/valley*.toml as ESRI ASCII grids (docs/mpm_terrain.md).

The ground: a 30 degree slope falling along easting from e = 0 to e = 0.5 m onto a level floor
0.02 m high that runs on to e = 0.9 m, with a shallow channel across northing (2 (n - 0.1)^2
higher at the sides). The release: a lens on the upper slope, centred at e = 0.2, n = 0.1, with
semi-axes 0.13 m (easting) and 0.075 m (northing) and 0.1 m thick at its centre, thinning as
1 - r^2 to nothing at its rim; its volume is pi a b T / 2 = 1.53e-3 m^3. Both rasters are
georeferenced at a UTM-sized corner (easting 512000, northing 5170000, elevation 431.5), which
the scenes' terrain.origin removes again.

  scripts/make_valley.py [--cell 0.005] [--north 0.2] [--out mpm/scenes/valley]
writes ground.asc and top.asc. The shipped rasters use the defaults (180 x 40 cells of 5 mm);
--cell 0.0009 --north 0.9 gives the 1000 x 1000 rasters of the set-up benchmark.
"""
import argparse
import math
import os

E0, N0, Z0 = 512000.0, 5170000.0, 431.5  # georeferenced lower-left corner and datum
SLOPE_END, FLOOR, TAN = 0.5, 0.02, math.tan(math.radians(30.0))
LENS_E, LENS_N, LENS_A, LENS_B, LENS_T = 0.2, 0.1, 0.13, 0.075, 0.1


def ground(e, n):
    return FLOOR + max(0.0, SLOPE_END - e) * TAN + 2.0 * (n - 0.1) ** 2


def lens(e, n):
    r2 = ((e - LENS_E) / LENS_A) ** 2 + ((n - LENS_N) / LENS_B) ** 2
    return LENS_T * max(0.0, 1.0 - r2)


def write(path, cell, ncols, nrows, f):
    with open(path, "w") as out:
        out.write(f"ncols {ncols}\nnrows {nrows}\nxllcorner {E0}\nyllcorner {N0}\ncellsize {cell}\n"
                  "NODATA_value -9999\n")
        for r in range(nrows):  # northern row first
            n = (nrows - 1 - r + 0.5) * cell
            out.write(" ".join(f"{Z0 + f((c + 0.5) * cell, n):.6f}" for c in range(ncols)) + "\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cell", type=float, default=0.005, help="cell size [m]")
    ap.add_argument("--north", type=float, default=0.2, help="extent along northing [m]")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "..", "mpm", "scenes", "valley"))
    a = ap.parse_args()
    ncols, nrows = round(0.9 / a.cell), round(a.north / a.cell)
    os.makedirs(a.out, exist_ok=True)
    write(os.path.join(a.out, "ground.asc"), a.cell, ncols, nrows, ground)
    write(os.path.join(a.out, "top.asc"), a.cell, ncols, nrows, lambda e, n: ground(e, n) + lens(e, n))
    print(f"{a.out}: ground.asc, top.asc ({ncols} x {nrows} cells of {a.cell} m)")


if __name__ == "__main__":
    main()
