#!/usr/bin/env python3
"""Error against run time of the GPU mesh series.

Reads the rows that `scripts/gpu.sh series` writes to series.csv (default
docs/figures/mpm_series_h100.csv), takes for each scene the finest fp64 run of the
phase-transition model as the reference (the column: 1 mm at the fixed step; the flume: the
finest grid run), and writes
  <stem>_errors.csv  every full run with its run-out error and the paper's time for its grid,
  <stem>.png         |run-out error| against wall time, one panel per scene,
and prints the Markdown table of docs/mpm_results.md.
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from png_output import save_png  # noqa: E402  (beside this script)


src = sys.argv[1] if len(sys.argv) > 1 else "docs/figures/mpm_series_h100.csv"
stem = src[:-4] if src.endswith(".csv") else src
# Tables C-1 and C-2 of the paper (MODEL.md 12): minutes on an i9-13900K + RTX 4080 (Taichi).
PAPER_MIN = {"column": {10: 1.24, 5: 6.78, 2.5: 100.1, 1: 240.53},
             "flume": {20: 4.24, 10: 8.67, 5: 240.01, 2.5: 450.53}}
FULL_T = {"column": 1.1, "flume": 3.1}

rows = list(csv.DictReader(line for line in open(src) if not line.startswith("#")))
for r in rows:
    r["h"] = float(r["h_mm"])
    r["full"] = r["exit"] == "0" and abs(float(r["t_end"] or 0) - FULL_T[r["scene"]]) < 1e-6


def reference(scene):
    cands = [r for r in rows if r["scene"] == scene and r["full"] and r["precision"] == "fp64"
             and r["model"] == "pt" and not r["extra"]]
    h = min(r["h"] for r in cands)
    finest = [r for r in cands if r["h"] == h]
    fixed = [r for r in finest if r["dt_mode"] == "fixed"]
    return (fixed or finest)[0]


out = []
for scene in ("column", "flume"):
    ref = reference(scene)
    for r in rows:
        if r["scene"] != scene or not r["full"]:
            continue
        e = float(r["runout_final"]) / float(ref["runout_final"]) - 1
        e4 = float(r["runout_0.4"]) / float(ref["runout_0.4"]) - 1
        out.append(dict(scene=scene, h_mm=r["h_mm"], dt=r["dt_mode"] if r["dt_mode"] != "fixed" else "fixed " + r["dt_max"],
                        precision=r["precision"], model=r["model"], extra=r["extra"], steps=r["steps"],
                        wall_s=r["wall_s"], device_us_per_step=r["device_us_per_step"],
                        runout_final=r["runout_final"], runout_error=f"{e:.4f}", runout_0p4=r["runout_0.4"],
                        runout_0p4_error=f"{e4:.4f}", height_final=r["height_final"],
                        paper_min=PAPER_MIN[scene].get(r["h"], ""),
                        reference="yes" if r is ref else ""))

with open(stem + "_errors.csv", "w", newline="") as f:
    f.write(f"# from {src} by scripts/plot_error_vs_time.py; errors relative to the reference row\n")
    w = csv.DictWriter(f, fieldnames=list(out[0].keys()))
    w.writeheader()
    w.writerows(out)

fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
style = {("fixed", "fp64"): ("o", "C0"), ("fixed", "fp32"): ("s", "C1"),
         ("cfl", "fp64"): ("^", "C2"), ("cfl", "fp32"): ("v", "C3")}
for ax, scene in zip(axes, ("column", "flume")):
    for r in out:
        if r["scene"] != scene or r["model"] != "pt" or r["extra"] or r["reference"]:
            continue
        kind = "cfl" if r["dt"].startswith("cfl") else "fixed"
        m, c = style[(kind, r["precision"])]
        err = max(abs(float(r["runout_error"])), 1e-4)
        ax.loglog(float(r["wall_s"]), err, m, color=c)
        ax.annotate(r["h_mm"], (float(r["wall_s"]), err), textcoords="offset points", xytext=(4, 3), fontsize=7)
    for (kind, prec), (m, c) in style.items():
        ax.plot([], [], m, color=c, label=f"{'CFL 0.5' if kind == 'cfl' else 'fixed dt'}, {prec}")
    ax.set_title(f"{scene} (labels: grid in mm)")
    ax.set_xlabel("wall time on one H100 [s]")
    ax.set_ylabel("|final run-out error| vs finest fp64 run [-]\n(below 1e-4 drawn at 1e-4)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
fig.suptitle("MPM error against run time (phase-transition model; paper: 1.2-450 min per run on an RTX 4080)")
fig.tight_layout()
save_png(fig, stem + ".png", 110)

print("| scene | grid [mm] | time step | precision | model | steps | wall [s] | device us/step | run-out [m] | error | at t_flow 0.4 s [m] | paper [min] |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
for r in out:
    label = r["model"] + (f" ({r['extra']})" if r["extra"] else "")
    err = "reference" if r["reference"] else f"{100 * float(r['runout_error']):+.1f} %"
    print(f"| {r['scene']} | {r['h_mm']} | {r['dt']} | {r['precision']} | {label} | {r['steps']} | {float(r['wall_s']):.1f} | "
          f"{r['device_us_per_step']} | {float(r['runout_final']):.4f} | {err} | {r['runout_0p4']} | {r['paper_min']} |")
print("wrote", stem + "_errors.csv", "and", stem + ".png", file=sys.stderr)
