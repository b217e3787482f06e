#!/usr/bin/env python3
"""Figures of the ensemble method of granflow calibrate (algorithm.method = "ensemble").

usage: plot_posterior.py OUTDIR [title]
Reads OUTDIR/posterior.csv, posterior_summary.csv and ensemble_curves.csv; writes
OUTDIR/posterior.png (pairwise scatter of the computed final members, histograms on the
diagonal, the written set as a cross) and OUTDIR/ensemble_fit.png (each curve's data with its
sd, the 5-95 % envelope and median of the final members' predictions, the best member).
Without matplotlib it prints a message and exits 0.
"""
import csv
import math
import os
import sys
from collections import OrderedDict

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    plt = None

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))


def number(cell):
    """An empty cell is a value granflow could not compute."""
    return float(cell) if cell else float("nan")


def short(key):
    return key.split(".", 1)[-1]


def plot_posterior(outdir, title):
    from png_output import save_png

    rows = list(csv.DictReader(open(os.path.join(outdir, "posterior.csv"))))
    summary = {r["key"]: r for r in csv.DictReader(open(os.path.join(outdir, "posterior_summary.csv")))}
    keys = [k for k in rows[0].keys() if k not in ("member", "misfit", "ok")]
    ok = [r for r in rows if r["ok"] == "1"]
    vals = {k: [number(r[k]) for r in ok] for k in keys}
    n = len(keys)
    size = max(2.2, min(3.2, 12.0 / n))
    fig, axes = plt.subplots(n, n, figsize=(size * n + 0.5, size * n + 0.5), squeeze=False)
    for i, ki in enumerate(keys):
        for j, kj in enumerate(keys):
            ax = axes[i][j]
            if j > i:
                ax.axis("off")
                continue
            s = summary[kj]
            if i == j:
                ax.hist(vals[ki], bins=max(8, min(30, len(ok) // 4)), color="C0", alpha=0.7)
                for q in ("q05", "q95"):
                    ax.axvline(number(s[q]), color="k", ls="--", lw=0.8)
                ax.axvline(number(s["median"]), color="k", lw=1.0)
                ax.axvline(number(s["fitted"]), color="C3", lw=1.2)
                ax.set_yticks([])
            else:
                ax.plot(vals[kj], vals[ki], ".", color="C0", ms=3, alpha=0.6)
                ax.plot([number(s["fitted"])], [number(summary[ki]["fitted"])], "x", color="C3", ms=8, mew=2)
            if i == n - 1:
                ax.set_xlabel(short(kj))
            else:
                ax.set_xticklabels([])
            if j == 0 and i > 0:
                ax.set_ylabel(short(ki))
            ax.tick_params(labelsize=7)
            ax.grid(alpha=0.3)
    fig.suptitle("%s  posterior: %d of %d final members; dashed: 5/95 %%, black: median, red: written set"
                 % (title, len(ok), len(rows)), fontsize=9)
    fig.tight_layout()
    save_png(fig, os.path.join(outdir, "posterior.png"), 110)
    plt.close(fig)


def plot_envelope(outdir, title):
    from png_output import save_png
    from plot_calibration import ABSCISSA_UNITS, ylabel

    panels = OrderedDict()
    for r in csv.DictReader(open(os.path.join(outdir, "ensemble_curves.csv"))):
        panels.setdefault((r["data_column"], r["model_output"]), OrderedDict()).setdefault(r["experiment"], []).append(r)
    n = len(panels)
    cols = min(3, n)
    nrows = (n + cols - 1) // cols
    fig, axes = plt.subplots(nrows, cols, figsize=(5 * cols, 4 * nrows), squeeze=False)
    for ax, ((dcol, out), exps) in zip(axes.flat, panels.items()):
        ys = []
        for k, (name, pts) in enumerate(exps.items()):
            c = "C%d" % (k % 10)
            x = [number(p["x"]) for p in pts]
            y = [number(p["data"]) for p in pts]
            sd = [number(p["sd"]) for p in pts]
            ys += y
            ax.fill_between(x, [number(p["q05"]) for p in pts], [number(p["q95"]) for p in pts], color=c, alpha=0.25,
                            lw=0)
            ax.errorbar(x, y, yerr=sd, fmt="o", color=c, ms=3, lw=0.6, label=name)
            ax.plot(x, [number(p["best"]) for p in pts], "-", color=c, lw=1.2)
        finite = [v for v in ys if not math.isnan(v)]
        if finite and min(finite) > 0 and max(finite) / min(finite) > 100:
            ax.set_yscale("log")
        q = pts[0]["quantity"]
        ax.set_xlabel("%s (%s) [%s]" % (pts[0]["abscissa"], q, ABSCISSA_UNITS.get(q, "-")))
        ax.set_ylabel(ylabel(dcol, out))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    fig.suptitle(title + "  markers: data +/- sd, band: 5-95 % of the final ensemble, line: best member", fontsize=9)
    fig.tight_layout()
    save_png(fig, os.path.join(outdir, "ensemble_fit.png"), 110)
    plt.close(fig)


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    if plt is None:
        print("plot_posterior.py: matplotlib is not installed; posterior.png and ensemble_fit.png not drawn")
        return
    title = sys.argv[2] if len(sys.argv) > 2 else ""
    plot_posterior(sys.argv[1], title)
    plot_envelope(sys.argv[1], title)


if __name__ == "__main__":
    main()
