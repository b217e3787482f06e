#!/usr/bin/env python3
"""Writes the slit barrier of mpm/scenes/valley_barrier*.toml as an ASCII STL (docs/mpm_meshes.md).

Two plates across the valley's floor, one closed box each (the file holds both shells), leaving a
slit between them. Coordinates are the scene's (x down the valley, y up, z across) in metres and
float32-exact, so that what an STL stores is what is written here.

    scripts/make_slit_barrier.py [OUT]   (default mpm/scenes/valley/slit_barrier.stl)
"""
import sys

X = (0.4375, 0.484375)   # along the flow: 4.7 cm thick (2.3 cells of the CI copy's 2 cm), at the slope's foot
Y = (0.0, 0.1875)         # from below the ground (y = 0.03 to 0.06 there) to 13 cm above it
PLATES = [(0.0, 0.0703125), (0.1328125, 0.2)]   # across: plates of 7.0 and 6.7 cm, a slit of 6.25 cm (0.2: within float32 of the grid edge)

QUADS = [((0, 0, 0), (0, 0, 1), (0, 1, 1), (0, 1, 0)), ((1, 0, 0), (1, 1, 0), (1, 1, 1), (1, 0, 1)),
         ((0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)), ((0, 1, 0), (0, 1, 1), (1, 1, 1), (1, 1, 0)),
         ((0, 0, 0), (0, 1, 0), (1, 1, 0), (1, 0, 0)), ((0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1))]


def box(lo, hi):
    """Twelve outward triangles of the box [lo, hi]."""
    for q in QUADS:
        c = [[hi[d] if v[d] else lo[d] for d in range(3)] for v in q]
        yield c[0], c[1], c[2]
        yield c[0], c[2], c[3]


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "mpm/scenes/valley/slit_barrier.stl"
    lines = ["solid slit_barrier"]
    for z0, z1 in PLATES:
        for tri in box((X[0], Y[0], z0), (X[1], Y[1], z1)):
            lines += ["facet normal 0 0 0", "outer loop"] + ["vertex %r %r %r" % tuple(v) for v in tri] + ["endloop", "endfacet"]
    lines.append("endsolid slit_barrier")
    with open(out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("wrote", out)


if __name__ == "__main__":
    main()
