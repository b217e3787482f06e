#!/usr/bin/env python3
"""Run-out error against wall time for the MPM mesh series (docs/figures/mpm_column_mesh_series.csv)."""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from png_output import save_png  # noqa: E402  (beside this script)


src = sys.argv[1] if len(sys.argv) > 1 else "docs/figures/mpm_column_mesh_series.csv"
dst = sys.argv[2] if len(sys.argv) > 2 else "docs/figures/mpm_column_mesh_series.png"
rows = list(csv.DictReader(line for line in open(src) if not line.startswith("#")))
fig, ax = plt.subplots(1, 2, figsize=(10, 4))
marker = {"cpu": ("^", "C2"), "cuda": ("o", "C0")}
for r in rows[:-1]:
    err = abs(float(r["runout_error_vs_1mm"]))
    m, c = marker[r["backend"]]
    ax[0].loglog(float(r["wall_s"]), err, m, color=c)
    ax[0].loglog(60 * float(r["paper_wall_min_rtx4080"]), err, "s", color="C1")
    ax[0].annotate(r["h_mm"] + " mm", (float(r["wall_s"]), err), textcoords="offset points", xytext=(5, 5))
for b in sorted({r["backend"] for r in rows[:-1]}):
    ax[0].plot([], [], marker[b][0], color=marker[b][1],
               label="granflow, " + ("CPU twin, 1 thread" if b == "cpu" else "GPU") + " (device, commit: CSV)")
ax[0].plot([], [], "s", color="C1", label="paper's wall time for that grid (Taichi, RTX 4080)")
ax[0].set_xlabel("wall time [s]")
ax[0].set_ylabel("|run-out error| against the 1 mm run [-]")
ax[0].legend(loc="lower center", fontsize=8)
ax[0].grid(True, which="both", alpha=0.3)
h = [float(r["h_mm"]) for r in rows]
ax[1].semilogx(h, [float(r["runout_m"]) for r in rows], "o-", label="granflow")
ax[1].axhline(0.42, color="k", ls="--", label="paper, 1 mm (about 0.42 m)")
ax[1].set_xlabel("grid spacing h [mm]")
ax[1].set_ylabel("final run-out [m]")
ax[1].invert_xaxis()
ax[1].legend()
ax[1].grid(True, which="both", alpha=0.3)
fig.suptitle("Column collapse mesh series (phase transition, quadratic B-splines)")
fig.tight_layout()
save_png(fig, dst, 110)
print("wrote", dst)
