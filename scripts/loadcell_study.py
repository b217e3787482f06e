#!/usr/bin/env python3
"""The load-cell flume study (docs/mpm_results.md): force histories, peaks, impulses and the
momentum-flux estimate, from the runs of `scripts/gpu.sh loadcell-pt loadcell-fr loadcell-ens`.

  scripts/loadcell_study.py RESULTS [--figures docs/figures] [--phi-c 38]

RESULTS holds pt_ANGLE/ and fr_ANGLE/ (obstacle_forces.csv, gauges.csv) and optionally
ens45/ (summary.csv, members.tgz). Writes loadcell_forces.png, loadcell_peaks.png,
loadcell_sensitivity.png and loadcell_table.csv into --figures, and prints the tables as Markdown.

The load cell reads the force normal to its plate: F = Fx cos(a) - Fy sin(a), down the slope.
Peaks are of the 5 ms running mean of the 1 ms samples (a load cell's response is not a single
step's). Estimate at the gauge two cells upstream, 5 ms means of depth h (normal to the slope),
velocity u (along it) and density rho: F_est = rho h u^2 + K rho g h^2 / 2, K = 1 and K_a.
"""
import argparse
import csv
import io
import math
import os
import re
import sys
import tarfile

G = 9.81
FLUME_WIDTH = 0.25  # m, assumed: 50 kg over the box's 0.15 m^2 at rho_p / (1 + e0) = 1316 kg/m^3


def read_rows(path_or_file):
    f = open(path_or_file, newline="") if isinstance(path_or_file, str) else path_or_file
    with f:
        rd = csv.reader(f)
        head = [re.sub(r" \[.*\]$", "", h) for h in next(rd)]
        return [dict(zip(head, r)) for r in rd]


def running_mean(v, k):
    """Centred running mean over k samples (fewer at the ends)."""
    out = []
    for i in range(len(v)):
        lo, hi = max(0, i - k // 2), min(len(v), i + k // 2 + 1)
        out.append(sum(v[lo:hi]) / (hi - lo))
    return out


def load_force(rows, angle):
    c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    t, f, fmax = [], [], []
    for r in rows:
        if r["boundary"] != "load cell" or r["part"] != "total" or float(r["t_flow"]) <= 0:
            continue
        t.append(float(r["t_flow"]))
        f.append(float(r["Fx"]) * c - float(r["Fy"]) * s)
        fmax.append(float(r["F_max"]))
    return t, f, fmax


def summarise(t, f, fmax, window):
    fs = running_mean(f, window) if window > 1 else f
    i = max(range(len(fs)), key=lambda k: fs[k])
    dts = [t[0]] + [t[k] - t[k - 1] for k in range(1, len(t))]
    impulse = sum(fk * dk for fk, dk in zip(f, dts))
    tail = [fk for tk, fk in zip(t, f) if tk >= t[-1] - 0.1]
    return {"peak": fs[i], "t_peak": t[i], "impulse": impulse, "final": sum(tail) / len(tail),
            "step_max": max(fmax) if fmax else float("nan"), "smooth": fs, "t_arrive": next(
                (tk for tk, fk in zip(t, fs) if fk > 0.05 * fs[i]), float("nan"))}


def gauge_estimate(path, gauge, t_peak, window, k_a):
    rows = [r for r in read_rows(path) if float(r["t_flow"]) > 0 and r["gauge"] == gauge]
    if not rows:
        return {}
    t = [float(r["t_flow"]) for r in rows]
    h, u, rho = ([float(r[k]) for r in rows] for k in ("depth", "u", "density"))
    hm, um, rm = (running_mean(v, window) for v in (h, u, rho))
    i = min(range(len(t)), key=lambda k: abs(t[k] - t_peak))
    est = lambda k, j: rm[j] * hm[j] * um[j] ** 2 + k * rm[j] * G * hm[j] ** 2 / 2
    return {"h": hm[i], "u": um[i], "rho": rm[i], "est1": est(1.0, i), "estKa": est(k_a, i),
            "dyn": rm[i] * hm[i] * um[i] ** 2}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results")
    ap.add_argument("--figures", default="docs/figures")
    ap.add_argument("--phi-c", type=float, default=38.0, help="critical-state friction angle for K_a [deg]")
    ap.add_argument("--measured", help="CSV of measured histories: angle [deg], t [s], F [N] (over the flume width)")
    a = ap.parse_args()
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    k_a = (1 - math.sin(math.radians(a.phi_c))) / (1 + math.sin(math.radians(a.phi_c)))
    runs = {}
    for name in sorted(os.listdir(a.results)):
        m = re.fullmatch(r"(pt|fr)_(\d+)", name)
        path = os.path.join(a.results, name, "obstacle_forces.csv")
        if not m or not os.path.exists(path):
            continue
        model, angle = m.group(1), int(m.group(2))
        t, f, fmax = load_force(read_rows(path), angle)
        if not t:
            print(f"{path}: no load-cell rows", file=sys.stderr)
            continue
        dt = t[1] - t[0]
        s = summarise(t, f, fmax, max(1, round(0.005 / dt)))
        gpath = os.path.join(a.results, name, "gauges.csv")
        if os.path.exists(gpath):
            for gname, tag in (("upstream", "up_"), ("approach", "")):
                s.update({tag + k: v for k, v in
                          gauge_estimate(gpath, gname, s["t_peak"], max(1, round(0.005 / dt)), k_a).items()})
        s["t"] = t
        runs[(model, angle)] = s
    if not runs:
        sys.exit(f"{a.results}: no pt_ANGLE or fr_ANGLE folder with obstacle_forces.csv")
    os.makedirs(a.figures, exist_ok=True)
    labels = {"pt": "phase transition", "fr": "frictional only"}
    measured = {}  # angle -> (t, F per unit width)
    if a.measured:
        for k, r in enumerate(read_rows(a.measured), start=2):
            try:
                ang, t, f = round(float(r["angle"])), float(r["t"]), float(r["F"]) / FLUME_WIDTH
            except (KeyError, ValueError) as e:
                sys.exit(f"{a.measured}:{k}: needs numbers in the columns 'angle [deg]', 't [s]', 'F [N]' ({e})")
            measured.setdefault(ang, ([], []))
            measured[ang][0].append(t)
            measured[ang][1].append(f)
        for (mo, ang), s in runs.items():
            if ang in measured:
                s["measured_peak"] = max(measured[ang][1])

    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    for ax, model in zip(axes, ("pt", "fr")):
        for (mo, ang), s in sorted(runs.items()):
            if mo == model:
                ax.plot(s["t"], s["smooth"], lw=1, label=f"{ang}°")
        for ang, (mt, mf) in sorted(measured.items()):
            ax.plot(mt, mf, "k--", lw=0.8, label=f"measured {ang}°")
        ax.set_title(labels[model])
        ax.set_xlabel("time after the gate opens [s]")
        ax.grid(alpha=0.3)
        ax.legend()
    axes[0].set_ylabel("force normal to the wall, 5 ms mean [N/m]")
    fig.tight_layout()
    fig.savefig(os.path.join(a.figures, "loadcell_forces.png"), dpi=120)

    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for model, mk in (("pt", "o-"), ("fr", "s-")):
        pts = sorted((ang, s) for (mo, ang), s in runs.items() if mo == model)
        if not pts:
            continue
        ax.plot([p[0] for p in pts], [p[1]["peak"] for p in pts], mk, label=f"peak, {labels[model]}")
        if "est1" in pts[0][1]:
            ax.plot([p[0] for p in pts], [p[1]["est1"] for p in pts], mk[0] + "--", mfc="none",
                    label=f"rho h u² + rho g h²/2, 0.1 m upstream, {labels[model]}")
            ax.plot([p[0] for p in pts], [p[1]["estKa"] for p in pts], mk[0] + ":", mfc="none",
                    label=f"the same with K_a, {labels[model]}")
        if "up_est1" in pts[0][1]:
            ax.plot([p[0] for p in pts], [p[1]["up_est1"] for p in pts], mk[0] + "-.", mfc="none", alpha=0.6,
                    label=f"rho h u² + rho g h²/2, two cells upstream, {labels[model]}")
    ax.set_xlabel("slope angle [°]")
    ax.set_ylabel("force on the wall [N/m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(a.figures, "loadcell_peaks.png"), dpi=120)

    with open(os.path.join(a.figures, "loadcell_table.csv"), "w", newline="") as fh:
        w = csv.writer(fh)
        cols = ["peak", "t_peak", "impulse", "final", "step_max", "up_h", "up_u", "up_rho", "up_est1", "up_estKa",
                "h", "u", "rho", "dyn", "est1", "estKa", "measured_peak"]
        w.writerow(["model", "angle [deg]", "peak [N/m]", "t_peak [s]", "impulse [N s/m]", "final [N/m]",
                    "largest step force [N/m]", "2 cells: h [m]", "2 cells: u [m/s]", "2 cells: rho [kg/m^3]",
                    "2 cells: estimate K=1 [N/m]", "2 cells: estimate K_a [N/m]", "approach: h [m]",
                    "approach: u [m/s]", "approach: rho [kg/m^3]", "approach: rho h u^2 [N/m]",
                    "approach: estimate K=1 [N/m]", "approach: estimate K_a [N/m]", "measured peak [N/m]",
                    "peak x width [N]"])
        for (mo, ang), s in sorted(runs.items()):
            w.writerow([mo, ang] + [f"{s.get(k, float('nan')):.4g}" for k in cols] +
                       [f"{s['peak'] * FLUME_WIDTH:.4g}"])

    print(f"K_a = {k_a:.3f} (phi_c = {a.phi_c:g} deg); flume width {FLUME_WIDTH} m (assumed)\n")
    print("| model | slope | peak (5 ms mean) | at t | x width | impulse | final | 2 cells up: h, u | estimate K = 1 / K_a | "
          "0.1 m up: h, u, rho | rho h u² | estimate K = 1 / K_a | peak / estimate K = 1 |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for (mo, ang), s in sorted(runs.items(), key=lambda kv: (kv[0][0] != "pt", kv[0][1])):
        g = lambda k, fmt: fmt.format(s[k]) if k in s else "-"
        print(f"| {labels[mo]} | {ang}° | {s['peak']:.0f} N/m | {s['t_peak']:.3f} s | {s['peak'] * FLUME_WIDTH:.0f} N | "
              f"{s['impulse']:.0f} N s/m | {s['final']:.0f} N/m | {g('up_h', '{:.3f}')} m, {g('up_u', '{:.2f}')} m/s | "
              f"{g('up_est1', '{:.0f}')} / {g('up_estKa', '{:.0f}')} N/m | {g('h', '{:.3f}')} m, {g('u', '{:.2f}')} m/s, "
              f"{g('rho', '{:.0f}')} kg/m³ | {g('dyn', '{:.0f}')} N/m | {g('est1', '{:.0f}')} / {g('estKa', '{:.0f}')} N/m | "
              + (f"{s['peak'] / s['est1']:.2f} |" if s.get("est1") else "- |"))

    ens = os.path.join(a.results, "ens45")
    if os.path.exists(os.path.join(ens, "summary.csv")):
        sensitivity(ens, a.figures, plt)


def sensitivity(ens, figures, plt):
    """45 deg peak (5 ms samples) over the design's variables: standardised linear coefficients."""
    summary = read_rows(os.path.join(ens, "summary.csv"))
    keys = [k for k in summary[0] if k not in ("member",) and k != "status"]
    keys = keys[:keys.index("runout")] if "runout" in keys else keys
    peaks = {}
    with tarfile.open(os.path.join(ens, "members.tgz")) as tf:
        for m in tf.getmembers():
            k = int(re.search(r"member_(\d+)", m.name).group(1))
            rows = read_rows(io.TextIOWrapper(tf.extractfile(m), encoding="utf-8"))
            t, f, fmax = load_force(rows, 45)
            if t:
                peaks[k] = summarise(t, f, fmax, 1)
    xs, ys = [], []
    for r in summary:
        k = int(r["member"])
        if r["status"] == "ok" and k in peaks:
            xs.append([math.log(float(r[c])) if "lift_speed" in c else float(r[c]) for c in keys])
            ys.append(peaks[k]["peak"])
    n, p = len(ys), len(keys)
    if n <= p + 1:
        print(f"{ens}: {n} finished members, too few for a fit", file=sys.stderr)
        return
    mean = lambda v: sum(v) / len(v)
    sd = lambda v: math.sqrt(sum((x - mean(v)) ** 2 for x in v) / (len(v) - 1))
    cols = list(zip(*xs))
    z = [[(x - mean(c)) / sd(c) for x, c in zip(row, cols)] for row in xs]
    yz = [(y - mean(ys)) / sd(ys) for y in ys]
    # least squares via the normal equations (p <= 4)
    A = [[sum(z[i][a] * z[i][b] for i in range(n)) for b in range(p)] for a in range(p)]
    bvec = [sum(z[i][a] * yz[i] for i in range(n)) for a in range(p)]
    for c in range(p):  # Gauss-Jordan
        piv = A[c][c]
        A[c] = [v / piv for v in A[c]]
        bvec[c] /= piv
        for r in range(p):
            if r != c:
                fct = A[r][c]
                A[r] = [vr - fct * vc for vr, vc in zip(A[r], A[c])]
                bvec[r] -= fct * bvec[c]
    pred = [sum(bvec[a] * z[i][a] for a in range(p)) for i in range(n)]
    r2 = 1 - sum((yz[i] - pred[i]) ** 2 for i in range(n)) / sum(v * v for v in yz)
    print(f"\n45 deg sensitivity: {n} members; peak {min(ys):.0f}-{max(ys):.0f} N/m (mean {mean(ys):.0f}); "
          f"R² {r2:.2f}; standardised coefficients: " +
          ", ".join(f"{k} {b:+.2f}" for k, b in zip(keys, bvec)))
    fig, axes = plt.subplots(1, p, figsize=(3 * p, 3), sharey=True)
    for a_, k in enumerate(keys):
        axes[a_].plot([row[a_] for row in xs], ys, "o", ms=3)
        axes[a_].set_xlabel(("ln " if "lift_speed" in k else "") + k, fontsize=8)
        axes[a_].grid(alpha=0.3)
    axes[0].set_ylabel("45° peak, 5 ms mean [N/m]")
    fig.tight_layout()
    fig.savefig(os.path.join(figures, "loadcell_sensitivity.png"), dpi=120)


if __name__ == "__main__":
    main()
