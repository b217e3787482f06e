#!/usr/bin/env python3
"""The points still moving in a granflow frame, with what a lone fringe point is made of.

    python3 scripts/stray_points.py FRAME.vtu [--speed 0.05] [--h H] [--ground 0]
        [--centre X Z] [--max 40]

Reads a VTU frame (any `output.format`, through plot_mpm.read_vtu) and lists the points faster
than --speed [m/s]: their distance from the axis (--centre, in plan), their height above a level
ground (--ground, in m and in grid spacings --h), speed, vertical velocity, p, q, T, eta_c and
how many other points lie within 2 h.
Written for issue 53's lone points that keep sliding over a no-slip ground
(docs/mpm_results.md, "Lone points of the fringe").
"""
import argparse

import numpy as np

from plot_mpm import read_vtu  # noqa: E402  (beside this script)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("frame")
    p.add_argument("--speed", type=float, default=0.05, help="list points faster than this [m/s]")
    p.add_argument("--h", type=float, default=0.0, help="grid spacing [m] (heights and neighbours in units of it)")
    p.add_argument("--ground", type=float, default=0.0, help="the level ground's height y [m]")
    p.add_argument("--centre", type=float, nargs=2, default=[0.0, 0.0], metavar=("X", "Z"))
    p.add_argument("--max", type=int, default=40, help="list at most this many points (the fastest)")
    a = p.parse_args()
    arr = read_vtu(a.frame, np)
    pos, vel, speed = arr["position"], arr["velocity"], arr["speed"]
    fields = [f for f in ("p", "q", "T", "eta_c") if f in arr]
    fast = np.flatnonzero(speed > a.speed)
    fast = fast[np.argsort(-speed[fast])]
    print(f"{a.frame}: {speed.size} points, {fast.size} faster than {a.speed} m/s")
    if fast.size == 0:
        return
    h = a.h
    shown = fast[:a.max]
    cols = ["point", "r [m]", "y-ground [m]"] + (["[h]"] if h > 0 else []) + ["speed", "vy"] + fields + \
           (["within 2h"] if h > 0 else [])
    print("  ".join(f"{c:>11}" for c in cols))
    for i in shown:
        x = pos[:, i]
        r = np.hypot(x[0] - a.centre[0], x[2] - a.centre[1]) if pos.shape[0] == 3 else x[0] - a.centre[0]
        y = x[1] - a.ground
        row = [f"{i:>11d}", f"{r:11.4f}", f"{y:11.5f}"] + ([f"{y / h:11.2f}"] if h > 0 else []) + \
              [f"{speed[i]:11.4f}", f"{vel[1, i]:11.4f}"] + [f"{arr[f][i]:11.4g}" for f in fields]
        if h > 0:  # the point itself is at distance 0
            row.append(f"{int(np.count_nonzero(((pos - x[:, None]) ** 2).sum(axis=0) < 4 * h * h)) - 1:11d}")
        print("  ".join(row))


if __name__ == "__main__":
    main()
