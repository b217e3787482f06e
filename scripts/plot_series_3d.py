#!/usr/bin/env python3
"""Error against run time of the 3D slab's and the valley's mesh series (issue 53).

    python3 scripts/plot_series_3d.py [CSV]   (default docs/figures/series3d.csv)

Reads the rows of `scripts/gpu.sh series-3d` (scene,h_mm,dt_s,steps,wall_s,...,runout_m,height_m,
exit). For each scene and measure (final run-out, final height) over its grids h1 > h2 > h3 > ...:
the error against the finest run, and with three or more grids the observed order and
Richardson's estimate from the three finest (plot_cylinder_series.richardson; "not monotone"
and the spread where the differences change sign), the error against that estimate and the grid
at which it falls to 5 % and 2 % (|e| = C h^p through the finest grid). Writes <stem>_errors.csv
and <stem>.png (|error| against the whole run's wall time) and prints the Markdown table.
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from plot_cylinder_series import error_axes, richardson, save_figure_and_errors, trend  # noqa: E402  (beside this script)


def analyse(rs, key):
    h = [r["h"] for r in rs]
    q = [float(r[key]) for r in rs]
    res = dict(h=h, q=q, order=None, qstar=None, h05=None, h02=None, spread=(max(q) - min(q)) / q[-1])
    est = richardson(h, q)
    if est:
        res.update(order=est["order"], qstar=est["qstar"], h05=est["h_for"](0.05), h02=est["h_for"](0.02))
    return res


def main():
    src = sys.argv[1] if len(sys.argv) > 1 else "docs/figures/series3d.csv"
    stem = src[:-4] if src.endswith(".csv") else src
    rows = [r for r in csv.DictReader(line for line in open(src) if not line.startswith("#")) if r["exit"] == "0"]
    for r in rows:
        r["h"] = float(r["h_mm"])
    scenes = sorted({r["scene"] for r in rows})
    fig, ax = plt.subplots(1, len(scenes), figsize=(5 * len(scenes), 4), squeeze=False)
    errs, table = [], []
    for k, sc in enumerate(scenes):
        rs = sorted((r for r in rows if r["scene"] == sc), key=lambda r: -r["h"])
        for key, mark, name in (("runout_m", "o-", "run-out"), ("height_m", "s--", "height")):
            res = analyse(rs, key)
            ref = res["qstar"] or res["q"][-1]
            lbl = "Richardson" if res["qstar"] else "finest"
            xs, ys = [], []
            for r, q in zip(rs, res["q"]):
                e = q / ref - 1
                errs.append(dict(scene=sc, measure=name, h_mm=r["h_mm"], wall_s=r["wall_s"], value=q,
                                 error=f"{e:.4f}", reference=lbl))
                if e != 0:
                    xs.append(float(r["wall_s"]))
                    ys.append(max(abs(e), 1e-4))
            ax[0][k].loglog(xs, ys, mark, label=f"{name} (against {lbl})")
            table.append((sc, name, rs, res))
        ax[0][k].set_title(sc)
        error_axes(ax[0][k], "|error|")
    save_figure_and_errors(fig, "3D scenes: error against run time (fp32, step in proportion to h)", stem, errs)
    print("| scene | measure | h [mm]: value [m] | observed order | Richardson [m] | finest against it | h for 5 % / 2 % [mm] |")
    print("|---|---|---|---|---|---|---|")
    for sc, name, rs, res in table:
        vals = ", ".join(f"{r['h_mm']}: {q:.4f}" for r, q in zip(rs, res["q"]))
        if res["order"] is None:
            why = "two grids: no order" if len(res["q"]) < 3 else trend(res["q"])
            print(f"| {sc} | {name} | {vals} | {why}; spread {100 * res['spread']:.1f} % | - | - | - |")
        else:
            e = res["q"][-1] / res["qstar"] - 1
            fmt = lambda v: "-" if v is None else f"{v:.2g}"  # noqa: E731
            print(f"| {sc} | {name} | {vals} | {res['order']:.2f} | {res['qstar']:.4f} | {100 * e:+.1f} % | "
                  f"{fmt(res['h05'])} / {fmt(res['h02'])} |")


if __name__ == "__main__":
    main()
