#!/usr/bin/env python3
"""Writes the calibration jobs on the measured KFSDB tests (data/lab/kfsdb) from tests.csv:

  python3 scripts/make_kfs_jobs.py [--out data/calibration]

kfs_fit.toml: the frictional parameters fitted on FIT (oedometer, drained triaxial at two
densities and two pressures, undrained tests with a per-test free e0), every other test with a
known e0 predicted blind (role = "predict"); kfs_fit_short.toml: the CI version (fewer tests and
evaluations, perturbed start). Each test's initial state is its first data row: e0 from the
file (undrained: free), effective axial stress sigma_v0 and k0 = radial/axial. Oedometer tests
start at the seating stress SEAT (first row at or above it) and follow the file's stress column.
"""
import argparse
import csv
import os

HERE = os.path.dirname(os.path.abspath(__file__))
LAB = os.path.join(HERE, "..", "data", "lab", "kfsdb")

# The split (docs/calibration_sand.md): fitted tests; every other test with a known e0 is held out.
FIT_OE = ["OE2", "OE10"]
FIT_TMD = ["TMD2", "TMD4", "TMD22", "TMD24"]        # e0 ~0.97 and ~0.70-0.74 at 100 and 300 kPa
FIT_TMU = ["TMU-MT1", "TMU2", "TMU8"]               # liquefying, compression, extension; e0 free
SHORT_OE, SHORT_TMD, SHORT_TMU = ["OE2"], ["TMD2", "TMD24"], ["TMU-MT1"]
SHORT_PREDICT = ["OE8", "TMD13", "TMD17"]    # held out in kfs_fit.toml too
SEAT = 10e3            # Pa, seating stress of the oedometer tests
TRIAXIAL_FROM_DATA = False  # triaxial tests: programme "data" (the eps_a column) or constant rate
E0_RANGE = (0.60, 1.10)  # bounds of a free per-test e0 (KFS: e_min 0.677, e_max 1.054)


def tests():
    with open(os.path.join(LAB, "tests.csv")) as f:
        return {r["test"]: r for r in csv.DictReader(l for l in f if not l.startswith("#"))}


def rows(name):
    with open(os.path.join(LAB, name + ".csv")) as f:
        return list(csv.DictReader(l for l in f if not l.startswith("#")))


def experiment(t, role):
    name, kind = t["test"], t["type"]
    out = ["[[experiments]]", 'name = "%s"' % name, 'kind = "element"', 'data = "../lab/%s"' % t["file"]]
    if role == "predict":
        out.append('role = "predict"')
    test = ['model = "frictional"', 'max_steps = 20000']
    if kind == "oedometer":
        r = rows(name)
        seat = next(x for x in r if float(x["sigma_a"]) >= SEAT)
        out += ['abscissa = "sigma_a"', 'quantity = "strain"', 'model_abscissa = "sigma_n"',
                'abscissa_reverses = true', 'duplicates = "average"', "range = [%g, 1e9]" % SEAT,
                'targets = { e = "e" }', "", "[experiments.test]",
                'path = "oedometric"', 'programme = "data"', 'control_column = "sigma_a"', 'control = "stress"',
                "rate = 1000", "e0 = %s                 # the void ratio at the seating stress" % seat["e"],
                "sigma_v0 = %s              # seating stress: first row >= %g Pa" % (seat["sigma_a"], SEAT),
                'initial_stress = "k0"']
    else:
        drained = t["drainage"] == "drained"
        sa, sr = float(t["sigma_a0_eff_Pa"]), float(t["sigma_r0_eff_Pa"])
        targets = 'q = "q_axial", p = "p"' + (', eps_v = "eps_v"' if drained else "")
        strains = [float(x["eps_a"]) for x in rows(name)]
        end = max(strains, key=abs)
        out += ['abscissa = "eps_a"', 'quantity = "strain"', 'model_abscissa = "eps_a"',
                'abscissa_reverses = true', "reversal_tolerance = 2e-3", 'duplicates = "average"',
                "range = %s" % ("[0, 1]" if end > 0 else "[-1, 0]"),
                "targets = { %s }" % targets, "", "[experiments.test]",
                'path = "%s"' % ("drained_triaxial" if drained else "undrained_triaxial")]
        if TRIAXIAL_FROM_DATA:
            out += ['programme = "data"', 'control_column = "eps_a"', "rate = 0.01"]
        else:  # constant rate to the last row's strain: the same path as the data column within its
            # small reversals, at a third of the cost (log-spaced rows resolve the first percent)
            out += ['programme = "constant"', "rate = 0.01", "duration = %.6g" % (abs(end) / 0.01),
                    'direction = "%s"' % ("compression" if end > 0 else "extension"),
                    "outputs = 120", 'output_spacing = "log"']
        out += [
                "e0 = %s" % (t["e0"] if t["e0"] else "0.85               # free: [[free]] test.e0 below"),
                "sigma_v0 = %.6g" % sa, "k0 = %.6g" % (sr / sa)]
    return out + test


FREE = [  # key, lower, upper, log, start
    ("frictional.K0", 20, 2000, True, 150), ("frictional.nu", 0.05, 0.45, False, 0.25),
    ("frictional.n", 0.2, 1.0, False, 0.5), ("frictional.phi_c_deg", 25, 40, False, 33),
    ("frictional.e_ref", 0.9, 1.2, False, 1.0), ("frictional.lambda_c", 0.002, 0.2, True, 0.02),
    ("frictional.xi", 0.2, 1.5, False, 0.7), ("frictional.A_d", 0.1, 10, True, 1.0),
    ("frictional.k_p", 1e-4, 0.05, True, 0.002), ("frictional.n_p", 0.2, 5, False, 1.5),
    ("frictional.n_d", 0.2, 5, False, 1.5)]


# CI job: these free, from the shipped set with them perturbed (factor or offset).
SHORT_FREE = {"frictional.K0": 1.3, "frictional.phi_c_deg": -2.0, "frictional.e_ref": -0.015,
              "frictional.A_d": 0.7, "frictional.k_p": 1.5, "frictional.n_p": 0.8}


def perturbed_start(out):
    """data/calibration/kfs_perturbed.toml: data/params/kfs_fitted.toml with SHORT_FREE applied."""
    import tomllib
    with open(os.path.join(HERE, "..", "data", "params", "kfs_fitted.toml"), "rb") as f:
        fitted = tomllib.load(f)["frictional"]
    lines = ["# Start of kfs_fit_short.toml: data/params/kfs_fitted.toml with six parameters perturbed",
             "# (scripts/make_kfs_jobs.py SHORT_FREE).", 'name = "Karlsruhe fine sand, perturbed shipped set"',
             'source = "data/params/kfs_fitted.toml, perturbed"', "", "[frictional]"]
    for k, v in fitted.items():
        d = SHORT_FREE.get("frictional." + k)
        if d is not None:
            v = v + d if k in ("phi_c_deg", "e_ref") else v * d
        lines.append("%s = %.10g" % (k, v))
    with open(os.path.join(out, "kfs_perturbed.toml"), "w") as f:
        f.write("\n".join(lines) + "\n")


def job(name, start, fit_oe, fit_tmd, fit_tmu, predict, algorithm, comment, output=None, free=True):
    t = tests()
    lines = ["# " + c for c in comment] + [
        'name = "%s"' % name, 'params = "%s"' % start, 'output = "%s"' % (output or name), ""]
    free_list = [f for f in FREE if f[0] in SHORT_FREE] if free == "short" else FREE if free else []
    for key, lo, hi, log, _ in free_list:
        lines += ["[[free]]", 'key = "%s"' % key, "lower = %g" % lo, "upper = %g" % hi] + (
            ["log = true"] if log else []) + [""]
    for n in fit_tmu:
        lines += ["[[free]]", 'key = "test.e0"', 'experiment = "%s"' % n, "lower = %g" % E0_RANGE[0],
                  "upper = %g" % E0_RANGE[1], ""]
    lines += ["[misfit]", 'scale = "linear"', 'normalise = "range"      # each curve by its range: q, p, eps_v, e alike', ""]
    lines += ["[algorithm]"] + algorithm + [""]
    for n in fit_oe + fit_tmd + fit_tmu:
        lines += experiment(t[n], "fit") + [""]
    for n in predict:
        lines += experiment(t[n], "predict") + [""]
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=os.path.join(HERE, "..", "data", "calibration"))
    a = ap.parse_args()
    t = tests()
    fitted = set(FIT_OE + FIT_TMD + FIT_TMU)
    predict = [n for n, r in t.items() if n not in fitted and r["e0"]]
    full = job("kfs_fit", "kfs_start.toml", FIT_OE, FIT_TMD, FIT_TMU, predict,
               ['global = "none"', 'local = "LN_BOBYQA"', "local_evaluations = 1500", "seed = 1"],
               ["Frictional law on measured Karlsruhe fine sand (KFSDB; data/lab/SOURCES.md): fit on 2 oedometer,",
                "4 drained and 3 undrained tests, predict the other %d tests with a known e0 blind." % len(predict),
                "Written by scripts/make_kfs_jobs.py; docs/calibration_sand.md."], output="kfs_fitted")
    undrained = [n for n, r in t.items() if r["drainage"] == "undrained"]
    und = job("kfs_undrained_e0", "kfs_fitted", [], [], undrained, [],
              ['global = "none"', 'local = "LN_BOBYQA"', "local_evaluations = 3000", "seed = 1"],
              ["The %d undrained KFSDB tests have no known e0: with the shipped set (data/params/kfs_fitted.toml)" % len(undrained),
               "fixed, each test's e0 alone is fitted, to ask whether the law can follow each test at some e0.",
               "Written by scripts/make_kfs_jobs.py; docs/calibration_sand.md."], output="kfs_undrained_e0", free=False)
    with open(os.path.join(a.out, "kfs_undrained_e0.toml"), "w") as f:
        f.write(und)
    with open(os.path.join(a.out, "kfs_fit.toml"), "w") as f:
        f.write(full)
    perturbed_start(a.out)
    short = job("kfs_fit_short", "kfs_perturbed.toml", SHORT_OE, SHORT_TMD, SHORT_TMU, SHORT_PREDICT,
                ['global = "none"', 'local = "LN_BOBYQA"', "local_evaluations = 400", "seed = 1"],
                ["CI version of kfs_fit.toml (test MeasuredTests.ShortKfsFitRecoversTheShippedHeldOutErrors):",
                 "six parameters free from the shipped set perturbed, four tests fitted, three held out.",
                 "Written by scripts/make_kfs_jobs.py; docs/calibration_sand.md."], free="short")
    with open(os.path.join(a.out, "kfs_fit_short.toml"), "w") as f:
        f.write(short)
    print("wrote kfs_fit.toml (%d predicted) and kfs_fit_short.toml" % len(predict))


if __name__ == "__main__":
    main()
