#!/usr/bin/env python3
"""Error against run time of the axisymmetric collapse's mesh series (3D; issue 53).

    python3 scripts/plot_cylinder_series.py [CSV]   (default docs/figures/cylinder_series.csv)

Reads scripts/cylinder_summary.py's rows (scripts/gpu.sh part cylinder), keeps the baseline
runs that ran to their end (variants "baseline" and "rest", the baseline ended once at rest), and for each aspect ratio a takes two measures q (the deposit's edge
radius and the final height H_inf) over the grids h1 > h2 > h3:
  - the error against the finest run, q(h) / q(h_finest) - 1;
  - with three grids, Richardson's estimate q* = q3 + (q3 - q2) / (r^p - 1), r = h2 / h3, with the
    observed order p = ln((q1 - q2) / (q2 - q3)) / ln(h1 / h2) (grids refined by a constant ratio;
    otherwise p solved numerically); a series that is not monotone, or whose differences grow, has no order ("not monotone", "monotone, differences growing")
    and the spread (max - min) / finest are reported instead;
  - the R0/h at which the error against q* falls to 5 % and 2 %, from |e(h)| = C h^p fitted at the
    finest grid.
Writes <stem>_errors.csv and <stem>.png (|error| of the edge against the whole run's wall time, one
line per a), and prints the Markdown tables of docs/mpm_results.md.
"""
import csv
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from png_output import save_png  # noqa: E402  (beside this script)


def observed_order(h, q):
    """Order p from three grids h[0] > h[1] > h[2]; None where the differences change sign."""
    d1, d2 = q[0] - q[1], q[1] - q[2]
    if d1 == 0 or d2 == 0 or (d1 > 0) != (d2 > 0):
        return None
    r21, r32 = h[0] / h[1], h[1] / h[2]
    # (q1 - q2) / (q2 - q3) = (r21^p - 1) r32^p / (r32^p - 1): bisection on p in (0.05, 8)
    target = d1 / d2

    def f(p):
        return (r21 ** p - 1) * r32 ** p / (r32 ** p - 1) - target

    lo, hi = 0.05, 8.0
    if f(lo) * f(hi) > 0:
        return None
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if f(lo) * f(mid) <= 0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def trend(q):
    """Why three grids give no order: the differences change sign, or they grow."""
    d1, d2 = q[-3] - q[-2], q[-2] - q[-1]
    return "monotone, differences growing" if (d1 > 0) == (d2 > 0) and d1 != 0 and d2 != 0 else "not monotone"


def richardson(h, q):
    """From the three finest grids (h descending): the observed order, Richardson's estimate and
    h_for(target), the grid at which |e| = C h^p through the finest grid falls to target (None
    where the finest grid is exact); None without three grids or without an order."""
    if len(q) < 3:
        return None
    p = observed_order(h[-3:], q[-3:])
    if p is None:
        return None
    qs = q[-1] + (q[-1] - q[-2]) / ((h[-2] / h[-1]) ** p - 1)
    e_fin = abs(q[-1] / qs - 1)
    return dict(order=p, qstar=qs, h_for=lambda tgt: h[-1] * (tgt / e_fin) ** (1 / p) if e_fin > 0 else None)


def analyse(rows, key):
    """Per a: the grids, values, errors against the finest and Richardson, order, 5 % / 2 % R0/h."""
    out = {}
    for a in sorted({r["a"] for r in rows}):
        rs = sorted((r for r in rows if r["a"] == a and r.get(key)), key=lambda r: -r["h"])
        if len(rs) < 2:
            continue
        h = [r["h"] for r in rs]
        q = [float(r[key]) for r in rs]
        res = dict(h=h, q=q, rows=rs, order=None, qstar=None, r05=None, r02=None,
                   spread=(max(q) - min(q)) / q[-1])
        est = richardson(h, q)
        if est:
            res.update(order=est["order"], qstar=est["qstar"])
            r0 = rs[-1]["r0"]
            for tgt, k in ((0.05, "r05"), (0.02, "r02")):
                hg = est["h_for"](tgt)
                res[k] = r0 / hg if hg else None
        out[a] = res
    return out


def error_axes(ax, ylabel):
    """An |error| against wall time panel: labels, the 5 % and 2 % lines, grid, legend."""
    ax.set_xlabel("whole run, wall time [s]")
    ax.set_ylabel(ylabel)
    ax.axhline(0.05, color="0.6", lw=0.8, ls="--")
    ax.axhline(0.02, color="0.6", lw=0.8, ls=":")
    ax.grid(True, which="both", lw=0.3)
    ax.legend(fontsize=8)


def save_figure_and_errors(fig, title, stem, errs):
    """<stem>.png and the rows of <stem>_errors.csv."""
    fig.suptitle(title)
    fig.tight_layout()
    save_png(fig, stem + ".png", 110)
    with open(stem + "_errors.csv", "w", newline="") as f:
        w = csv.DictWriter(f, list(errs[0].keys()), lineterminator="\n")
        w.writeheader()
        w.writerows(errs)


def main():
    src = sys.argv[1] if len(sys.argv) > 1 else "docs/figures/cylinder_series.csv"
    stem = src[:-4] if src.endswith(".csv") else src
    rows = [r for r in csv.DictReader(line for line in open(src) if not line.startswith("#"))
            if r["variant"] in ("baseline", "rest") and r["exit"] == "0" and r.get("edge_m")]
    for r in rows:
        r["a"] = float(r["a"])
        r["h"] = float(r["h_mm"]) / 1e3
        r["r0"] = float(r["r0_m"])
    edge, height = analyse(rows, "edge_m"), analyse(rows, "height_m")
    errs = []
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for a, res in edge.items():
        ref = res["qstar"] if res["qstar"] else res["q"][-1]
        lbl = "Richardson" if res["qstar"] else "finest"
        xs, ys, hs = [], [], []
        for r, q in zip(res["rows"], res["q"]):
            e = q / ref - 1
            hq = next(x for x in height[a]["rows"] if x["case"] == r["case"]) if a in height else None
            eh = (float(hq["height_m"]) / (height[a]["qstar"] or height[a]["q"][-1]) - 1) if hq else float("nan")
            errs.append(dict(a=a, r0_over_h=r["r0_over_h"], h_mm=r["h_mm"], wall_s=r["wall_s"],
                             edge_m=q, edge_error=f"{e:.4f}", height_m=r["height_m"],
                             height_error=f"{eh:.4f}", reference=lbl))
            if r.get("wall_s") and e != 0:  # the finest run is its own reference: no point
                xs.append(float(r["wall_s"]))
                ys.append(abs(e))
                hs.append(abs(eh))
        ax[0].loglog(xs, [max(y, 1e-4) for y in ys], "o-", label=f"a = {a:g} (against {lbl})")
        ax[1].loglog(xs, [max(y, 1e-4) for y in hs], "s-", label=f"a = {a:g}")
    for k, t in enumerate(("deposit edge radius", "final height")):
        error_axes(ax[k], f"|error| of the {t}")
    save_figure_and_errors(fig, "Axisymmetric collapse: error against run time (quarter cylinder, fp32)", stem, errs)
    print("| a | measure | R0/h: value | observed order | Richardson | finest against it | R0/h for 5 % / 2 % |")
    print("|---|---|---|---|---|---|---|")
    for name, table in (("edge [m]", edge), ("H_inf [m]", height)):
        for a, res in table.items():
            vals = ", ".join(f"{r['r0_over_h']}: {q:.4f}" for r, q in zip(res["rows"], res["q"]))
            if res["order"] is None:
                why = "two grids: no order" if len(res["q"]) < 3 else trend(res["q"])
                print(f"| {a:g} | {name} | {vals} | {why}; spread {100 * res['spread']:.1f} % | - | - | - |")
            else:
                e = res["q"][-1] / res["qstar"] - 1
                print(f"| {a:g} | {name} | {vals} | {res['order']:.2f} | {res['qstar']:.4f} | {100 * e:+.1f} % | "
                      f"{res['r05']:.0f} / {res['r02']:.0f} |")


if __name__ == "__main__":
    main()
