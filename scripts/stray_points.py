#!/usr/bin/env python3
"""The points still moving in a granflow frame, with what a lone fringe point is made of.

    python3 scripts/stray_points.py FRAME.vtu [--speed 0.05] [--h H] [--ground 0]
        [--centre X Z] [--max 40]

Reads a raw-appended VTU frame (granflow's default `output.format`; Python's standard library
only, no numpy) and lists the points faster than --speed [m/s]: their distance from the axis
(--centre, in plan), their height above a level ground (--ground, in m and in grid spacings
--h), speed, vertical velocity, p, q, T, eta_c and how many other points lie within 2 h.
Written for issue 53's lone points that keep sliding over a no-slip ground
(docs/mpm_results.md, "Axisymmetric collapse").
"""
import argparse
import math
import re
import struct
import sys
from array import array

TYPES = {"Float32": "f", "Float64": "d", "Int64": "q", "UInt64": "Q", "Int32": "i", "UInt32": "I",
         "UInt8": "B", "Int8": "b"}


def read_frame(path):
    with open(path, "rb") as f:
        data = f.read()
    mark = data.find(b"<AppendedData")
    if mark < 0:
        sys.exit(f"{path}: no raw AppendedData (written with output.format = \"appended\"?)")
    head = data[:mark].decode("ascii", "replace")
    start = data.index(b"_", mark) + 1
    n = int(re.search(r'NumberOfPoints="(\d+)"', head).group(1))
    arrays = {}
    for m in re.finditer(r'<DataArray type="(\w+)" Name="([^"]+)" NumberOfComponents="(\d+)" format="appended" '
                         r'offset="(\d+)"', head):
        kind, name, comp, off = m.group(1), m.group(2), int(m.group(3)), int(m.group(4))
        if kind not in TYPES:
            continue
        (nbytes,) = struct.unpack_from("<Q", data, start + off)
        a = array(TYPES[kind])
        a.frombytes(data[start + off + 8:start + off + 8 + nbytes])
        if sys.byteorder != "little":
            a.byteswap()
        arrays[name] = (a, comp)
    return n, arrays


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("frame")
    p.add_argument("--speed", type=float, default=0.05, help="list points faster than this [m/s]")
    p.add_argument("--h", type=float, default=0.0, help="grid spacing [m] (heights and neighbours in units of it)")
    p.add_argument("--ground", type=float, default=0.0, help="the level ground's height y [m]")
    p.add_argument("--centre", type=float, nargs=2, default=[0.0, 0.0], metavar=("X", "Z"))
    p.add_argument("--max", type=int, default=40, help="list at most this many points (the fastest)")
    a = p.parse_args()
    n, arr = read_frame(a.frame)
    pos, dim = arr["position"]
    vel, _ = arr["velocity"]
    fields = [f for f in ("p", "q", "T", "eta_c") if f in arr]
    fast = []
    for i in range(n):
        s = math.sqrt(sum(vel[dim * i + d] ** 2 for d in range(dim)))
        if s > a.speed:
            fast.append((s, i))
    fast.sort(reverse=True)
    print(f"{a.frame}: {n} points, {len(fast)} faster than {a.speed} m/s")
    if not fast:
        return
    h = a.h
    shown = fast[:a.max]
    counts = {}
    if h > 0:  # points within 2 h of each listed one: one pass over all points, through the cells near them
        cell = lambda i: tuple(int(math.floor(pos[dim * i + d] / h)) for d in range(dim))
        near = {}
        for _, i in shown:
            c = cell(i)
            for off in range(3 ** dim):
                k = tuple(c[d] + (off // 3 ** d) % 3 - 1 for d in range(dim))
                near.setdefault(k, []).append(i)
        counts = {i: 0 for _, i in shown}
        for j in range(n):
            k = cell(j)
            if k in near:
                for i in near[k]:
                    if i != j and sum((pos[dim * i + d] - pos[dim * j + d]) ** 2 for d in range(dim)) < 4 * h * h:
                        counts[i] += 1
    cols = ["point", "r [m]", "y-ground [m]"] + (["[h]"] if h > 0 else []) + ["speed", "vy"] + fields + \
           (["within 2h"] if h > 0 else [])
    print("  ".join(f"{c:>11}" for c in cols))
    for s, i in shown:
        x = [pos[dim * i + d] for d in range(dim)]
        r = math.hypot(x[0] - a.centre[0], x[2] - a.centre[1]) if dim == 3 else x[0] - a.centre[0]
        y = x[1] - a.ground
        row = [f"{i:>11d}", f"{r:11.4f}", f"{y:11.5f}"] + ([f"{y / h:11.2f}"] if h > 0 else []) + \
              [f"{s:11.4f}", f"{vel[dim * i + 1]:11.4f}"] + [f"{arr[f][0][i]:11.4g}" for f in fields] + \
              ([f"{counts[i]:11d}"] if h > 0 else [])
        print("  ".join(row))


if __name__ == "__main__":
    main()
