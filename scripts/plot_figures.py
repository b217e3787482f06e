#!/usr/bin/env python3
"""Plots the CSVs written by `granflow figures` (Figs. 4-7, DEM comparison, work-precision).

Usage: python3 scripts/plot_figures.py [folder]   (default docs/figures)
"""
import csv
import math
import os
import sys
from collections import OrderedDict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from png_output import save_png  # noqa: E402  (beside this script)


def read(path, key):
    """Long-format CSV -> OrderedDict label -> dict column -> list."""
    curves = OrderedDict()
    with open(path) as f:
        for row in csv.DictReader(f):
            c = curves.setdefault(row[key], {})
            for k, v in row.items():
                try:
                    c.setdefault(k, []).append(float(v))
                except ValueError:
                    c.setdefault(k, []).append(float("nan"))
    return curves


def save(fig, folder, name):
    fig.tight_layout()
    try:
        save_png(fig, os.path.join(folder, name), 110)
    finally:
        plt.close(fig)
    print("  wrote", os.path.join(folder, name))


# DEM units: stresses in rho_p d^2 gammadot^2, temperature in (d gammadot)^2
DEM_LABEL = {"p": r"$p\,/\,(\rho_p d^2 \dot\gamma^2)$ [-]", "s": r"$s\,/\,(\rho_p d^2 \dot\gamma^2)$ [-]",
             "T": r"$T\,/\,(d \dot\gamma)^2$ [-]"}


def kpa(v):
    return [x / 1e3 for x in v]


def fig4(folder):
    c = read(os.path.join(folder, "fig4.csv"), "e0")
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for e0, d in c.items():
        ax[0].plot(kpa(d["sigma_n"]), kpa(d["tau"]), label="e0 = %s" % e0)
        ax[1].plot(d["gamma"], kpa(d["tau"]), label="e0 = %s" % e0)
    ax[0].set_xlabel("vertical stress sigma_n [kPa]")
    ax[0].set_ylabel("shear stress tau [kPa]")
    ax[0].set_title("Fig. 4a: stress path (frictional, Table 1)")
    ax[1].set_xlabel("shear strain gamma [-]")
    ax[1].set_ylabel("shear stress tau [kPa]")
    ax[1].set_title("Fig. 4b: undrained simple shear, 100 kPa, K0")
    for a in ax:
        a.legend()
        a.grid(alpha=0.3)
    save(fig, folder, "fig4.png")


def fig5(folder):
    c = read(os.path.join(folder, "fig5.csv"), "e0")
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for e0, d in c.items():
        ax[0].plot(d["shear_rate"], d["sigma_n"], label="e0 = %s" % e0)
        ax[1].plot(d["shear_rate"], d["tau"], label="e0 = %s" % e0)
    ax[0].set_ylabel("normal stress sigma_n [Pa]")
    ax[1].set_ylabel("shear stress tau [Pa]")
    for a in ax:
        a.set_xlabel("shear rate [1/s]")
        a.legend()
        a.grid(alpha=0.3)
    ax[0].set_title("Fig. 5: collisional only (Table 2), 50 t 1/s")
    save(fig, folder, "fig5.png")


def fig6(folder):
    c = read(os.path.join(folder, "fig6.csv"), "e0")
    s = read(os.path.join(folder, "fig6_sweep.csv"), "e0")
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for i, (e0, d) in enumerate(c.items()):
        col = "C%d" % i
        ax[0].loglog(d["shear_rate"], d["sigma_n"], col, label="e0 = %s, Fig. 6 protocol" % e0)
        ax[1].loglog(d["shear_rate"], d["tau"], col, label="e0 = %s, Fig. 6 protocol" % e0)
        sw = s[e0]
        ax[0].loglog(sw["shear_rate"], sw["sigma_n"], col + "o", ms=3, mfc="none", label="e0 = %s, steady sweep" % e0)
        ax[1].loglog(sw["shear_rate"], sw["tau"], col + "o", ms=3, mfc="none", label="e0 = %s, steady sweep" % e0)
    ax[0].set_ylabel("normal stress sigma_n [Pa]")
    ax[1].set_ylabel("shear stress tau [Pa]")
    for a in ax:
        a.set_xlabel("shear rate [1/s]")
        a.legend(fontsize=7)
        a.grid(alpha=0.3, which="both")
    ax[0].set_title("Fig. 6: full model, 500 Pa")
    save(fig, folder, "fig6.png")


def fig7(folder):
    c = read(os.path.join(folder, "fig7.csv"), "e0")
    s = read(os.path.join(folder, "fig7_fixed_strain.csv"), "gamma_end")
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.2))
    d = list(c.values())[0]
    pos = lambda v: [x if x > 0 else float("nan") for x in v]
    ax[0].loglog(d["shear_rate"], pos(d["sigma_n_c"]), "C0", label="normal, collisional")
    ax[0].loglog(d["shear_rate"], pos(d["tau_c"]), "C1", label="shear, collisional")
    ax[0].loglog(d["shear_rate"], pos(d["sigma_n_f"]), "C0--", label="normal, frictional (0 after gamma=0.004)")
    ax[0].loglog(d["shear_rate"], pos(d["tau_f"]), "C1--", label="shear, frictional")
    ax[0].set_title("Fig. 7 (e0 = 1.10), Fig. 6 protocol")
    for i, (g, sw) in enumerate(s.items()):
        ax[1].loglog(sw["shear_rate"], pos(sw["tau_f"]), "C%d--" % i, label="frictional, gamma = %s" % g)
        ax[1].loglog(sw["shear_rate"], pos(sw["tau_c"]), "C%d-" % i, label="collisional, gamma = %s" % g)
        ax[2].semilogx(sw["shear_rate"], sw["K_col"], "C%d" % i, label="gamma = %s" % g)
    ax[1].set_title("e0 = 1.10: shear stress parts at fixed strain")
    ax[2].set_title("collisional share K_col = q_c / (q_c + q_f)")
    ax[0].set_ylabel("stress [Pa]")
    ax[1].set_ylabel("shear stress [Pa]")
    ax[2].set_ylabel("K_col [-]")
    for a in ax:
        a.set_xlabel("shear rate [1/s]")
        a.legend(fontsize=7)
        a.grid(alpha=0.3, which="both")
    save(fig, folder, "fig7.png")


def dem(folder):
    path = os.path.join(folder, "dem_comparison.csv")
    rows = list(csv.DictReader(open(path)))
    groups = OrderedDict()
    for r in rows:
        groups.setdefault((r["mu_p"], r["eps_n"]), []).append({k: float(v) for k, v in r.items()})
    fig, ax = plt.subplots(2, 3, figsize=(15, 8))
    for j, mu in enumerate(sorted({k[0] for k in groups})):
        keys = [k for k in groups if k[0] == mu]
        for i, k in enumerate(keys):
            g = groups[k]
            nu = [r["nu"] for r in g]
            for a, q in zip(ax[j], ["p", "s", "T"]):
                a.semilogy(nu, [r[q + "_dem"] for r in g], "C%do" % i, ms=3, label="DEM e=%s" % k[1])
                a.semilogy(nu, [r[q + "_model"] for r in g], "C%d-" % i, label="model e=%s" % k[1])
                a.set_title("%s, mu_p = %s" % (q, mu))
                a.set_ylabel(DEM_LABEL[q])
                a.set_xlabel("solid fraction nu [-]")
        ax[j][0].legend(fontsize=6, ncol=2)
    for a in ax.flat:
        a.grid(alpha=0.3, which="both")
    save(fig, folder, "dem_comparison.png")


def bench(folder):
    path = os.path.join(folder, "bench_element.csv")
    if not os.path.exists(path):
        return
    rows = [r for r in csv.DictReader(open(path)) if r["error"] not in ("nan", "")]
    cases = OrderedDict()
    for r in rows:
        cases.setdefault(r["case"], []).append(r)
    fig, ax = plt.subplots(1, len(cases), figsize=(6 * len(cases), 4.5))
    if len(cases) == 1:
        ax = [ax]
    for a, (name, rs) in zip(ax, cases.items()):
        for solver, mk in (("cvode", "o-"), ("incremental", "s-")):
            pts = [(float(r["cpu_s"]), max(float(r["error"]), 1e-16), r["setting"]) for r in rs if r["solver"] == solver]
            if not pts:
                continue
            a.loglog([p[0] for p in pts], [p[1] for p in pts], mk, label=solver)
            for p in pts:
                a.annotate(p[2], (p[0], p[1]), fontsize=6)
        a.set_xlabel("CPU time [s]")
        a.set_ylabel("max relative error of sigma_n, tau [-]")
        a.set_title("work-precision: " + name)
        a.legend()
        a.grid(alpha=0.3, which="both")
    save(fig, folder, "work_precision.png")


def main():
    folder = sys.argv[1] if len(sys.argv) > 1 else "docs/figures"
    for f in (fig4, fig5, fig6, fig7, dem, bench):
        try:
            f(folder)
        except FileNotFoundError as e:
            print("  skipped %s: %s" % (f.__name__, e))


if __name__ == "__main__":
    main()
