#!/usr/bin/env python3
"""Flow curves of a joint steady-shear fit (flow_points.csv of granflow calibrate, issue 25).

usage: plot_flow_curves.py RUN_DIR
Writes into RUN_DIR: flow_<n>.png per group (p, s, T against the solid fraction, DEM markers,
model lines, log scale), flow_groups.png (every group, one panel per quantity and friction) and
flow_mu_I.png (s/p against I = 1/sqrt(p), data and model).
"""
import csv
import math
import os
import re
import sys
from collections import OrderedDict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from png_output import save_png  # noqa: E402  (beside this script)


def number(cell):
    return float(cell) if cell else float("nan")


def read(run_dir):
    groups = OrderedDict()
    with open(os.path.join(run_dir, "flow_points.csv")) as f:
        for row in csv.DictReader(f):
            g = groups.setdefault(row["group"], {k: [] for k in ("nu", "p", "s", "T", "p_model", "s_model", "T_model")})
            for k in g:
                g[k].append(number(row[k]))
    return groups


def label(group):
    m = re.search(r"contact_friction_mu=([0-9.]+),restitution_e=([0-9.]+)", group)
    return "mu_p = %s, e = %s" % m.groups() if m else group


def main():
    run_dir = sys.argv[1]
    groups = read(run_dir)
    names = {"p": r"$p/(\rho_p d^2\dot\gamma^2)$", "s": r"$s/(\rho_p d^2\dot\gamma^2)$", "T": r"$T/(d\dot\gamma)^2$"}
    colours = {"p": "tab:blue", "s": "tab:orange", "T": "tab:green"}
    for i, (g, d) in enumerate(groups.items()):
        fig, ax = plt.subplots(figsize=(5, 3.6))
        for q in ("p", "s", "T"):
            ax.plot(d["nu"], d[q], "o", color=colours[q], ms=4, label=names[q] + " DEM")
            ax.plot(d["nu"], d[q + "_model"], "-", color=colours[q], label="model")
        ax.axvline(0.57, color="0.6", lw=0.8, ls=":")
        ax.set_yscale("log")
        ax.set_xlabel("solid fraction")
        ax.set_title(label(g), fontsize=10)
        ax.legend(fontsize=6, ncol=3)
        fig.tight_layout()
        save_png(fig, os.path.join(run_dir, "flow_%d.png" % (i + 1)), 110)
        plt.close(fig)

    frictions = sorted({label(g).split(",")[0] for g in groups})
    fig, axes = plt.subplots(len(frictions), 3, figsize=(12, 3.4 * len(frictions)), squeeze=False)
    cmap = plt.get_cmap("viridis")
    for r, fr in enumerate(frictions):
        members = [g for g in groups if label(g).startswith(fr + ",")]
        for j, q in enumerate(("p", "s", "T")):
            ax = axes[r][j]
            for k, g in enumerate(members):
                d = groups[g]
                c = cmap(k / max(1, len(members) - 1))
                ax.plot(d["nu"], d[q], "o", color=c, ms=3.5)
                ax.plot(d["nu"], d[q + "_model"], "-", color=c, label=label(g).split(", ")[1])
            ax.axvline(0.57, color="0.6", lw=0.8, ls=":")
            ax.set_yscale("log")
            ax.set_xlabel("solid fraction")
            ax.set_ylabel(names[q])
            ax.set_title("%s: %s (markers DEM, lines model)" % (fr, q), fontsize=9)
            if j == 0:
                ax.legend(fontsize=7)
    fig.tight_layout()
    save_png(fig, os.path.join(run_dir, "flow_groups.png"), 100)
    plt.close(fig)

    fig, axes = plt.subplots(1, len(frictions), figsize=(5.5 * len(frictions), 4), squeeze=False)
    for r, fr in enumerate(frictions):
        ax = axes[0][r]
        members = [g for g in groups if label(g).startswith(fr + ",")]
        for k, g in enumerate(members):
            d = groups[g]
            c = cmap(k / max(1, len(members) - 1))
            keep = [i for i, nu in enumerate(d["nu"]) if nu < 0.57]
            Id = [1 / math.sqrt(d["p"][i]) for i in keep]
            mud = [d["s"][i] / d["p"][i] for i in keep]
            Im = [1 / math.sqrt(d["p_model"][i]) if d["p_model"][i] > 0 else float("nan") for i in keep]
            mum = [d["s_model"][i] / d["p_model"][i] if d["p_model"][i] > 0 else float("nan") for i in keep]
            ax.plot(Id, mud, "o", color=c, ms=4)
            ax.plot(Im, mum, "-", color=c, label=label(g).split(", ")[1])
        ax.set_xscale("log")
        ax.set_xlabel(r"$I = \dot\gamma d/\sqrt{p/\rho_p}$")
        ax.set_ylabel("s/p")
        ax.set_title("%s, solid fraction < 0.57 (markers DEM, lines model)" % fr, fontsize=9)
        ax.legend(fontsize=7)
    fig.tight_layout()
    save_png(fig, os.path.join(run_dir, "flow_mu_I.png"), 100)
    plt.close(fig)


if __name__ == "__main__":
    main()
