#!/usr/bin/env python3
"""Per-test PNGs of a calibration on measured sand tests (DIR/test_curves.csv and DIR/tests.csv,
written by granflow calibrate when a job has held-out tests):

  plot_sand_tests.py DIR --phi-c DEG --csl E_REF,LAMBDA_C,XI,P_AT

tests_q_p.png (q-p' paths with the critical state lines q = M p' and q = -M_e p'),
tests_q_eps1.png, tests_epsv_eps1.png (drained), tests_e_logp.png (oedometer: e against
sigma_a; drained: e against p', with the critical state line e_c(p')). One panel per test:
markers = data, line = model with the fitted set; titles say fitted or held out.
"""
import argparse
import csv
import math
import os
from collections import OrderedDict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.ticker import NullFormatter, ScalarFormatter  # noqa: E402

from png_output import save_png  # noqa: E402  (beside this script)


def num(s):
    return float(s) if s else float("nan")


def load(d):
    tests = OrderedDict((r["test"], r) for r in csv.DictReader(open(os.path.join(d, "tests.csv"))))
    curves = {}
    for r in csv.DictReader(open(os.path.join(d, "test_curves.csv"))):
        c = curves.setdefault((r["test"], r["model_output"]), {"x": [], "data": [], "model": [], "abscissa": r["abscissa"]})
        c["x"].append(num(r["x"]))
        c["data"].append(num(r["data"]))
        c["model"].append(num(r["model"]))
    return tests, curves


def grid(n):
    cols = min(6, max(1, n))
    return (n + cols - 1) // cols, cols


def panels(tests, title, path, draw):
    names = [t for t in tests if draw(None, t, tests[t], dry=True)]
    if not names:
        return
    rows, cols = grid(len(names))
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.7 * rows), squeeze=False)
    for ax, t in zip(axes.flat, names):
        draw(ax, t, tests[t], dry=False)
        held = tests[t]["role"] == "predict"
        e0 = num(tests[t]["e0"])
        ax.set_title("%s  %s, e0 %.3f%s" % (t, "held out" if held else "fitted", e0,
                                             "*" if tests[t]["e0_fitted"] == "1" else ""),
                     fontsize=8, color="C0" if held else "k")
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    fig.suptitle(title + "  (markers: data, line: model; * e0 fitted per test)", fontsize=10)
    fig.tight_layout()
    save_png(fig, path, 80)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--phi-c", type=float, required=True)
    ap.add_argument("--csl", required=True)
    a = ap.parse_args()
    tests, curves = load(a.dir)
    s = math.sin(math.radians(a.phi_c))
    mc, me = 6 * s / (3 - s), 6 * s / (3 + s)
    e_ref, lam, xi, p_at = (float(v) for v in a.csl.split(","))
    ec = lambda p: e_ref * math.exp(-lam * (p / p_at) ** xi)
    q_of = lambda t: curves.get((t, "q_axial")) or curves.get((t, "q"))
    p_of = lambda t: curves.get((t, "p")) or curves.get((t, "p_f"))
    kpa = lambda v: [x / 1e3 for x in v]
    pct = lambda v: [100 * x for x in v]

    def measured(ax, x, y):  # the test's points
        ax.plot(x, y, ".", ms=2, color="0.4")

    def modelled(ax, x, y):  # the fitted law's curve
        ax.plot(x, y, "-", color="C3", lw=1.2)

    def q_p(ax, t, row, dry):
        q, p = q_of(t), p_of(t)
        if dry:
            return q is not None and p is not None
        measured(ax, kpa(p["data"]), kpa(q["data"]))
        modelled(ax, kpa(p["model"]), kpa(q["model"]))
        top = max(max(p["data"]), max(x for x in p["model"] if x == x)) / 1e3
        ax.plot([0, top], [0, mc * top], ":", color="k", lw=0.8)
        ax.plot([0, top], [0, -me * top], ":", color="k", lw=0.8)
        ax.set_xlabel("p' [kPa]", fontsize=7)
        ax.set_ylabel("q [kPa]", fontsize=7)

    def q_eps(ax, t, row, dry):
        q = q_of(t)
        if dry:
            return q is not None
        measured(ax, pct(q["x"]), kpa(q["data"]))
        modelled(ax, pct(q["x"]), kpa(q["model"]))
        ax.set_xlabel("eps_1 [%]", fontsize=7)
        ax.set_ylabel("q [kPa]", fontsize=7)

    def epsv_eps(ax, t, row, dry):
        v = curves.get((t, "eps_v"))
        if dry:
            return v is not None
        measured(ax, pct(v["x"]), pct(v["data"]))
        modelled(ax, pct(v["x"]), pct(v["model"]))
        ax.set_xlabel("eps_1 [%]", fontsize=7)
        ax.set_ylabel("eps_v [%] (contraction +)", fontsize=7)

    def e_logp(ax, t, row, dry):
        e, v, p = curves.get((t, "e")), curves.get((t, "eps_v")), p_of(t)
        if dry:
            return e is not None or (v is not None and p is not None)
        if e is not None:  # oedometer: e against the axial stress
            x, d, m = e["x"], e["data"], e["model"]
            ax.set_xlabel("sigma_a [kPa]", fontsize=7)
        else:  # drained: e from eps_v, against p'
            e0 = num(row["e0"])
            x = p["data"]
            d = [(1 + e0) * math.exp(-y) - 1 for y in v["data"]]
            m = [(1 + e0) * math.exp(-y) - 1 for y in v["model"]]
            modelled(ax, kpa(p["model"]), m)
            ax.set_xlabel("p' [kPa]", fontsize=7)
        measured(ax, kpa(x), d)
        if e is not None:
            modelled(ax, kpa(x), m)
        lo, hi = min(x), max(x)
        ps = [lo * (hi / lo) ** (i / 40.0) for i in range(41)] if lo > 0 else []
        ax.plot(kpa(ps), [ec(pp) for pp in ps], ":", color="k", lw=0.8)
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_ylabel("e", fontsize=7)

    d = a.dir
    panels(tests, "q-p' paths, CSL q = M p' (M = %.3f) and q = -M_e p' (M_e = %.3f)" % (mc, me),
           os.path.join(d, "tests_q_p.png"), q_p)
    panels(tests, "q against axial strain", os.path.join(d, "tests_q_eps1.png"), q_eps)
    panels(tests, "volumetric strain against axial strain", os.path.join(d, "tests_epsv_eps1.png"), epsv_eps)
    panels(tests, "void ratio against log stress; dotted: critical state line e_c(p')",
           os.path.join(d, "tests_e_logp.png"), e_logp)


if __name__ == "__main__":
    main()
