#!/usr/bin/env python3
"""PNGs of an ensemble's output directory (granflow ensemble SCENE DESIGN --out DIR).

    python3 scripts/plot_ensemble.py DIR [--data CSV]

Reads DIR/summary.csv and DIR/member_NNNN/profile_final.csv, and writes
  DIR/png/profiles.png        the final free surface of every member (failed members dashed),
                              coloured by the first varied value; --data CSV (x, y columns, e.g.
                              data/bui2008/deposit.csv) adds measured points;
  DIR/png/<quantity>.png      each summary quantity (final run-out and height, run-out at each
                              output time, max speed) against each varied value, one panel per
                              varied key.
Each PNG is written to a temporary name and renamed when complete. Without matplotlib it prints
a message and exits 0 (PNG output is optional).
"""
import argparse
import csv
import math
import os
import sys

from png_output import save_png  # noqa: E402  (beside this script)

FIXED = ("member", "status", "steps", "t_end", "wall_s", "message")
LABELS = {"runout": "final run-out [m]", "height": "final height [m]", "max_speed": "max speed after release [m/s]"}


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def number(s):
    try:
        return float(s)
    except (TypeError, ValueError):
        return math.nan


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dir")
    ap.add_argument("--data", help="measured surface to draw with the profiles (CSV with x and y columns)")
    a = ap.parse_args()
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("plot_ensemble.py: matplotlib not available, PNGs skipped", file=sys.stderr)
        return 0
    rows = read_csv(os.path.join(a.dir, "summary.csv"))
    if not rows:
        print("plot_ensemble.py: %s/summary.csv has no members" % a.dir, file=sys.stderr)
        return 1
    header = list(rows[0].keys())
    quantities = [h for h in header if h in LABELS or h.startswith("runout_t")]
    varied = [h for h in header if h not in FIXED and h not in quantities and h not in ("runout", "height")]
    quantities = ["runout", "height"] + [q for q in quantities if q not in ("runout", "height")]
    out = os.path.join(a.dir, "png")
    os.makedirs(out, exist_ok=True)
    cmap = plt.get_cmap("viridis")
    first = [number(r[varied[0]]) for r in rows] if varied else [0.0] * len(rows)
    lo, hi = min(first), max(first)

    fig, ax = plt.subplots(figsize=(8, 4))
    for r, v in zip(rows, first):
        path = os.path.join(a.dir, "member_%04d" % int(r["member"]), "profile_final.csv")
        if not os.path.exists(path):
            continue
        pr = read_csv(path)
        x = [number(p["x"]) for p in pr]
        y = [number(p["surface_y"]) for p in pr]
        c = cmap(0.5 if hi == lo else (v - lo) / (hi - lo))
        ax.plot(x, y, color=c, lw=1, ls="-" if r["status"] == "ok" else "--", alpha=0.8)
    if a.data:
        d = read_csv(a.data)
        keys = list(d[0].keys())
        ax.plot([number(p[keys[0]]) for p in d], [number(p[keys[1]]) for p in d], "k.", ms=3, label="measured")
        ax.legend()
    if varied:
        sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(lo, hi if hi > lo else lo + 1))
        fig.colorbar(sm, ax=ax, label=varied[0])
    ax.set_xlabel("x [m]")
    ax.set_ylabel("free surface [m]")
    ax.set_title("final profiles of %d members (dashed: failed)" % len(rows))
    ax.set_aspect("equal", adjustable="datalim")
    fig.tight_layout()
    save_png(fig, os.path.join(out, "profiles.png"), 150)
    plt.close(fig)

    ok = [r for r in rows if r["status"] == "ok"]
    for q in quantities:
        n = max(1, len(varied))
        fig, axes = plt.subplots(1, n, figsize=(3.2 * n, 3.2), squeeze=False)
        for ax, key in zip(axes[0], varied or ["member"]):
            ax.plot([number(r[key]) for r in ok], [number(r[q]) for r in ok], "o", ms=4)
            bad = [r for r in rows if r["status"] != "ok"]
            if bad:
                ax.plot([number(r[key]) for r in bad], [number(r[q]) for r in bad], "x", color="C3", label="failed")
                ax.legend(fontsize=7)
            ax.set_xlabel(key)
        label = LABELS.get(q, "run-out at t_flow = %s s [m]" % q[len("runout_t"):] if q.startswith("runout_t") else q)
        axes[0][0].set_ylabel(label)
        fig.tight_layout()
        save_png(fig, os.path.join(out, q + ".png"), 120)
        plt.close(fig)
    print("plot_ensemble.py: wrote %d PNGs in %s" % (1 + len(quantities), out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
