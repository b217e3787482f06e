#!/usr/bin/env python3
"""The deposit's shape of axisymmetric collapses (issue 53): azimuthally averaged thickness.

    python3 scripts/plot_cylinder_deposits.py OUT.png CASE_DIR [CASE_DIR ...]

CASE_DIR: a case of scripts/gpu.sh cylinder (scene.toml, and run/maps/deposit_thickness.asc or
deposit_thickness.asc.gz beside it). The final thickness map is averaged over annuli 0.1 R0 wide
about output.deposit_centre (R0 = 0.1 m, the generator's default). For each case prints the
centre thickness H_c (the mean of the innermost two annuli), the plateau radius (where the
profile stays within 5 % of H_c) and the mean slope of the flank between 25 % and 75 % of H_c, in degrees; plots h/H_c against r/R0,
one panel per parameter set.
"""
import gzip
import math
import os
import re
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from png_output import save_png  # noqa: E402  (beside this script)


R0 = 0.1
BIN = 0.1 * R0


def read_asc(path):
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        head = {}
        for _ in range(6):
            k, v = f.readline().split()
            head[k.lower()] = float(v)
        rows = [[float(x) for x in line.split()] for line in f if line.strip()]
    return head, rows


def profile(case):
    scene = open(os.path.join(case, "scene.toml")).read()
    cx, cz = (float(v) for v in re.search(r"deposit_centre = \[([^,]+), ([^\]]+)\]", scene).group(1, 2))
    name = re.search(r'^name = "(.*)"', scene, re.M).group(1)
    a = float(re.search(r"cylinder collapse a ([0-9.]+)", name).group(1))
    pset = name.rsplit(", ", 1)[-1]
    for p in ("run/maps/deposit_thickness.asc", "deposit_thickness.asc.gz", "run/maps/deposit_thickness.asc.gz"):
        if os.path.exists(os.path.join(case, p)):
            head, rows = read_asc(os.path.join(case, p))
            break
    else:
        raise SystemExit(f"{case}: no deposit_thickness.asc")
    c, n = head["cellsize"], int(head["nrows"])
    sums, counts = {}, {}
    for i, row in enumerate(rows):
        y = head["yllcorner"] + (n - 1 - i + 0.5) * c
        for j, t in enumerate(row):
            if t == head["nodata_value"]:
                continue
            x = head["xllcorner"] + (j + 0.5) * c
            k = int(math.hypot(x - cx, y - cz) / BIN)
            sums[k] = sums.get(k, 0.0) + t
            counts[k] = counts.get(k, 0) + 1
    r = [(k + 0.5) * BIN for k in sorted(sums)]
    h = [sums[k] / counts[k] for k in sorted(sums)]
    return a, pset, r, h


def shape(r, h):
    hc = sum(h[:2]) / 2
    plateau = 0.0
    for ri, hi in zip(r, h):
        if hi < 0.95 * hc:
            break
        plateau = ri
    # the flank: first radii where the profile falls below 75 % and 25 % of H_c
    r75 = next(ri for ri, hi in zip(r, h) if hi < 0.75 * hc)
    r25 = next(ri for ri, hi in zip(r, h) if hi < 0.25 * hc)
    slope = math.degrees(math.atan(0.5 * hc / (r25 - r75)))
    return hc, plateau, slope


def main():
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    cases = [profile(c) for c in sys.argv[2:]]
    sets = sorted({p for _, p, _, _ in cases})
    fig, ax = plt.subplots(1, len(sets), figsize=(5 * len(sets), 3.8), squeeze=False, sharey=True)
    print("| set | a | H_c/R0 | plateau radius / R0 | flank slope [deg] |")
    print("|---|---|---|---|---|")
    for a, pset, r, h in sorted(cases, key=lambda c: (c[1], c[0])):
        hc, plateau, slope = shape(r, h)
        print(f"| {pset} | {a:g} | {hc / R0:.3f} | {plateau / R0:.2f} | {slope:.1f} |")
        k = sets.index(pset)
        ax[0][k].plot([x / R0 for x in r], [y / hc for y in h], label=f"a = {a:g}")
    for k, pset in enumerate(sets):
        ax[0][k].set_title(pset)
        ax[0][k].set_xlabel("r / R0")
        ax[0][k].set_xlim(0, 9)
        ax[0][k].grid(True, lw=0.3)
        ax[0][k].legend(fontsize=8)
    ax[0][0].set_ylabel("thickness / centre thickness")
    fig.suptitle("Axisymmetric collapse: the deposit, azimuthally averaged (R0/h = 25, fp32)")
    fig.tight_layout()
    save_png(fig, sys.argv[1], 110)


if __name__ == "__main__":
    main()
