#!/usr/bin/env python3
"""Figure of MPM-Geomechanics' sliding-block verification against granflow (docs/mpm_terrain.md).

    GRANFLOW_EXTERNAL_OUT=out/terrain_external.csv build/tests/mpm/test_mpm \
        --gtest_filter=TerrainContact.ExternalSlidingBlock
    python3 scripts/plot_terrain_external.py out/terrain_external.csv docs/figures/terrain_external.png

Draws u(t) along the ground for mu 0 and 0.3: the closed form 1/2 g (sin 45 - mu cos 45) t^2,
MPM-Geomechanics' stored point (data/terrain_contact, only where their CSV has rows), and
granflow's point and centre of mass on the level raster with tilted gravity and on the 45 deg
raster. Prints the values at the last common time.
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

here = os.path.dirname(os.path.abspath(__file__))
src = sys.argv[1] if len(sys.argv) > 1 else "out/terrain_external.csv"
png = sys.argv[2] if len(sys.argv) > 2 else "docs/figures/terrain_external.png"

ours = {}
with open(src) as f:
    for r in csv.DictReader(f):
        ours.setdefault((r["ground"], float(r["mu"])), []).append(
            {k: float(r[k]) for k in ("t", "u_point", "u_centre", "u_exact", "w_centre")})

fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
for ax, mu in zip(axes, (0.0, 0.3)):
    theirs = os.path.join(here, "..", "data", "terrain_contact", f"mpm_results_mu_{mu:.1f}.csv")
    tt, ut = [], []
    with open(theirs) as f:
        for r in csv.DictReader(f):
            tt.append(float(r["Time"]))
            ut.append(float(r["Displacement_0"]))
    lv, sl = ours[("level", mu)], ours[("slope", mu)]
    ax.plot([r["t"] for r in lv], [r["u_exact"] for r in lv], "k-", lw=1, label="closed form")
    ax.plot(tt, ut, "ks", ms=4, mfc="none", label="MPM-Geomechanics, their point")
    ax.plot([r["t"] for r in lv], [r["u_point"] for r in lv], "C0--", label="granflow level + tilted g, point")
    ax.plot([r["t"] for r in lv], [r["u_centre"] for r in lv], "C0-", label="granflow level + tilted g, centre")
    ax.plot([r["t"] for r in sl], [r["u_point"] for r in sl], "C1--", label="granflow 45° raster, point")
    ax.plot([r["t"] for r in sl], [r["u_centre"] for r in sl], "C1-", label="granflow 45° raster, centre")
    ax.set_title(f"mu = {mu}")
    ax.set_xlabel("t [s]")
    ax.grid(alpha=0.3)
    t_end = tt[-1]
    for name, rows in (("level", lv), ("slope", sl)):
        r = min(rows, key=lambda r: abs(r["t"] - t_end))
        exact = 0.5 * 10 * (0.5 ** 0.5) * (1 - mu) * r["t"] ** 2
        print(f"mu {mu} {name}: t {r['t']:.2f} s point {r['u_point']:.3f} m centre {r['u_centre']:.3f} m "
              f"closed form {exact:.3f} m (centre {100 * (r['u_centre'] / exact - 1):+.2f} %, point "
              f"{100 * (r['u_point'] / exact - 1):+.2f} %), centre's rise {r['w_centre']:+.3f} m")
    exact_t = 0.5 * 10 * (0.5 ** 0.5) * (1 - mu) * t_end ** 2
    print(f"mu {mu} MPM-Geomechanics: t {t_end:.2f} s point {ut[-1]:.3f} m ({100 * (ut[-1] / exact_t - 1):+.2f} %)")
axes[0].set_ylabel("displacement along the ground [m]")
axes[0].legend(fontsize=7, loc="upper left")
fig.suptitle("10 m block on a 45° ground (MPM-Geomechanics' verification, commit 3911104)")
fig.tight_layout()
os.makedirs(os.path.dirname(png) or ".", exist_ok=True)
fig.savefig(png, dpi=120)
print("wrote", png)
