#!/usr/bin/env python3
"""Runs the option study of issue 25 and prints its table (docs/calibration_results.md, "Option study").

usage: flow_option_study.py [GRANFLOW] [OUT_DIR]
Every job of data/calibration/flow_study/ (scripts/make_flow_study.py) is fitted to the ten DEM
groups with its leave-one-group-out and leave-one-friction-out fits; the table gives per option
combination the worst fitted group and the worst left-out group in each window, and the band of
solid fraction where the worst fitted group's error is largest.
"""
import csv
import os
import subprocess
import sys
import time

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
STUDY = os.path.join(ROOT, "data", "calibration", "flow_study")
ORDER = ["base", "R", "D", "J", "JR", "JL", "JLR", "JD", "JDR", "JLD", "JLDR", "JDK", "JDRK", "JLDRK"]
NAMES = {"R": "restitution in the dissipation only", "J": "V_sd(mu_p)", "L": "correlation length",
         "D": "dilute uniform shear", "K": "friction factor of Eq. (24) free"}


def rows(path):
    if not os.path.exists(path):
        return []
    with open(path) as f:
        return list(csv.DictReader(f))


def short(group):
    return group.replace("dem[contact_friction_mu=", "mu_p ").replace(",restitution_e=", ", e ").rstrip("]")


def main():
    granflow = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build", "granflow")
    out = sys.argv[2] if len(sys.argv) > 2 else "flow_study_runs"
    os.makedirs(out, exist_ok=True)
    print("| options | worst fitted group, nu < 0.57 | its error by band 0-0.1 / 0.1-0.5 / 0.5-0.57 | worst fitted [0.1, 0.57) / [0.1, 0.555) "
          "| worst left-out group (LOGO), nu < 0.57 | LOGO [0.1, 0.57) / [0.1, 0.555) | worst other-friction group (LOFO), nu < 0.57 | time [s] |")
    print("|---|---|---|---|---|---|---|---|")
    for name in ORDER:
        job = os.path.join(STUDY, name + ".job.toml")
        if not os.path.exists(job):
            continue
        run = os.path.join(out, name)
        t0 = time.time()
        subprocess.run([granflow, "calibrate", job, "--out", run, "--force", "--threads", "2", "--quiet", "--no-plot"],
                       check=True, stderr=subprocess.DEVNULL)
        dt = time.time() - t0
        fitted = rows(os.path.join(run, "flow_scores.csv"))
        logo = rows(os.path.join(run, "flow_cv_groups.csv"))
        lofo = rows(os.path.join(run, "flow_cv_friction.csv"))
        w = [k for k in fitted[0] if k.startswith("rmse_")]
        b = [k for k in fitted[0] if k.startswith("band_")]

        def worst(rs, key):
            r = max(rs, key=lambda r: float(r[key]) if r[key] else -1)
            return r, float(r[key])

        wf, vf = worst(fitted, w[0])
        wg, vg = worst(logo, w[0])
        wl, vl = worst(lofo, w[0])
        label = "MODEL.md's model" if name == "base" else " + ".join(NAMES[c] for c in name)
        print("| %s | %.3f (%s) | %s | %.3f / %.3f | %.3f (%s) | %.3f / %.3f | %.3f (%s) | %.2f |" % (
            label, vf, short(wf["group"]), " / ".join("%.2f" % float(wf[k]) for k in b),
            worst(fitted, w[1])[1], worst(fitted, w[2])[1], vg, short(wg["group"]), worst(logo, w[1])[1],
            worst(logo, w[2])[1], vl, short(wl["group"]), dt))


if __name__ == "__main__":
    main()
