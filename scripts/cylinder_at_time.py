#!/usr/bin/env python3
"""The axisymmetric collapse's runs compared at one time (issue 53; docs/mpm_results.md): for a
mesh series whose finest run stopped early, the state of every run at the time it reached.

    python3 scripts/cylinder_at_time.py T RUN_DIR [RUN_DIR ...]

RUN_DIR holds a run's runout.csv and deposit.csv (the run folder, or what gpu.sh cylinder kept of
it). One line per run: the sample at time T (to 1e-6 s) and the run's last sample:

    run, t_s, ke_over_peak, edge_m, edge_axes_m, edge_diagonals_m, height_m, t_last_s, edge_last_m, height_last_m

ke_over_peak: kinetic energy at T over the run's peak; the edge is deposit.csv's (read at the
scene's output.edge_thickness), the height runout.csv's above the ground: the offset of its
reference line is taken from the scene (scene.toml in RUN_DIR or its parent; cylinder_summary.py).
"""
import csv
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cylinder_summary import line_height  # noqa: E402  (beside this script)


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def at(samples, t):
    for r in samples:
        if abs(float(r["t"]) - t) < 1e-6:
            return r
    sys.exit(f"{t} s is not a sample time of the run (last: {samples[-1]['t']} s)")


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    t = float(sys.argv[1])
    w = csv.writer(sys.stdout, lineterminator="\n")
    w.writerow(["run", "t_s", "ke_over_peak", "edge_m", "edge_axes_m", "edge_diagonals_m", "height_m",
                "t_last_s", "edge_last_m", "height_last_m"])
    for d in sys.argv[2:]:
        ro, de = rows(os.path.join(d, "runout.csv")), rows(os.path.join(d, "deposit.csv"))
        scene = next((p for p in (os.path.join(d, "scene.toml"), os.path.join(d, "..", "scene.toml"))
                      if os.path.exists(p)), None)
        if scene is None:
            sys.exit(f"{d}: no scene.toml here or in its parent: the height's reference line is not known")
        y0 = line_height(open(scene).read())
        peak = max(float(r["kinetic_energy"]) for r in ro)
        r, e = at(ro, t), at(de, t)
        w.writerow([d, f"{t:g}", f"{float(r['kinetic_energy']) / peak:.4f}", e["edge_radius"], e["edge_radius_axes"],
                    e["edge_radius_diagonals"], f"{float(r['height']) + y0:.6g}", ro[-1]["t"], de[-1]["edge_radius"],
                    f"{float(ro[-1]['height']) + y0:.6g}"])


if __name__ == "__main__":
    main()
