#!/usr/bin/env python3
"""Overlay fitted model curves on the data of a calibration (curves.csv written by granflow calibrate).

usage: plot_calibration.py curves.csv fit.png [title]
One panel per (data column, model output); one colour per experiment; markers = data,
dashed = model at the start, solid = fitted model.
"""
import csv
import os
import sys
from collections import OrderedDict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from png_output import save_png  # noqa: E402  (beside this script)


# Units of the model outputs (element-test result columns, docs/elementtest.md) and abscissae.
UNITS = {"tau": "Pa", "tau_f": "Pa", "tau_c": "Pa", "sigma_n": "Pa", "sigma_n_f": "Pa", "sigma_n_c": "Pa",
         "p": "Pa", "q": "Pa", "p_f": "Pa", "q_f": "Pa", "p_c": "Pa", "q_c": "Pa", "T": "m²/s²",
         "eta_c": "Pa s", "time": "s", "shear_rate": "1/s"}
ABSCISSA_UNITS = {"time": "s", "strain": "-", "shear_rate": "1/s", "solid_fraction": "-"}
# steady-shear data in the DEM's units (experiments.steady_shear.units = "dimensionless")
DIMLESS = {"p": r"$p\,/\,(\rho_p d^2 \dot\gamma^2)$", "tau": r"$\tau\,/\,(\rho_p d^2 \dot\gamma^2)$",
           "T": r"$T\,/\,(d \dot\gamma)^2$"}


def ylabel(data_column, output):
    if "dimless" in data_column and output in DIMLESS:
        return "%s  (model: %s) [-]" % (DIMLESS[output], output)
    return "%s  (model: %s) [%s]" % (data_column, output, UNITS.get(output, "-"))


def number(cell):
    """An empty cell is a value granflow could not compute (the model failed there)."""
    return float(cell) if cell else float("nan")


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    rows = list(csv.DictReader(open(sys.argv[1])))
    panels = OrderedDict()
    for r in rows:
        panels.setdefault((r["data_column"], r["model_output"]), OrderedDict()).setdefault(r["experiment"], []).append(r)
    n = len(panels)
    cols = min(3, n)
    nrows = (n + cols - 1) // cols
    fig, axes = plt.subplots(nrows, cols, figsize=(5 * cols, 4 * nrows), squeeze=False)
    for ax, ((dcol, out), exps) in zip(axes.flat, panels.items()):
        positive = True
        for k, (name, pts) in enumerate(exps.items()):
            c = "C%d" % (k % 10)
            x = [float(p["x"]) for p in pts]
            y = [float(p["data"]) for p in pts]
            m0 = [number(p["model_start"]) for p in pts]
            m1 = [number(p["model_fit"]) for p in pts]
            positive = positive and min(y) > 0
            ax.plot(x, y, "o", color=c, ms=4, label=name)
            ax.plot(x, m0, "--", color=c, lw=0.8, alpha=0.6)
            ax.plot(x, m1, "-", color=c, lw=1.5)
        span = max(float(p["data"]) for e in exps.values() for p in e) / max(
            1e-300, min(abs(float(p["data"])) for e in exps.values() for p in e))
        if positive and span > 100:
            ax.set_yscale("log")
        q = pts[0]["quantity"]
        ax.set_xlabel("%s (%s) [%s]" % (pts[0]["abscissa"], q, ABSCISSA_UNITS.get(q, "-")))
        ax.set_ylabel(ylabel(dcol, out))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    fig.suptitle((sys.argv[3] if len(sys.argv) > 3 else "") + "  markers: data, dashed: start, solid: fitted")
    fig.tight_layout()
    save_png(fig, sys.argv[2], 110)


if __name__ == "__main__":
    main()
