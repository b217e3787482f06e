#!/usr/bin/env python3
"""One row per axisymmetric-collapse run (issue 53; docs/mpm_results.md, "Axisymmetric collapse").

    python3 scripts/cylinder_summary.py CASE_DIR [CASE_DIR ...] > cylinder.csv

CASE_DIR is what scripts/make_cylinder_collapse.py wrote (scene.toml, whose first line names a,
R0 and h) with the run in CASE_DIR/run and granflow's printed summary in CASE_DIR/run.txt
(scripts/gpu.sh part cylinder). Columns:

    case            the folder's name
    a, r0_m, h_mm, r0_over_h, variant   the set-up (variant: the folder's name after "__")
    exit            granflow's exit code (CASE_DIR/exit; absent: 0)
    steps, wall_s, device_us_per_step   from run.txt
    runout_front_m  runout.csv's last run-out (along x on the symmetry plane)
    edge_m, edge_axes_m, edge_diagonals_m   deposit.csv's last edge radii (maps), read at
                    output.edge_thickness (the scene's; else one point spacing)
    edge_thickness_m  that thickness
    edge_spacing_m  the edge of the final thickness map (maps/deposit_thickness.asc) read at one
                    point spacing, granflow's default, in the same way (annuli one map cell wide
                    about output.deposit_centre, mean thickness at mean distance, linear between):
                    it shrinks with h, so it reads thinner fringes on finer grids
    height_m        runout.csv's last height above the ground (H_inf): measured from the scene's
                    [runout] line (y = 0 from the generator of 2026-12-07 on), else from the
                    grid's bottom (granflow's default line, y = -2 h), which is subtracted here
    spread_front, spread_edge   (R_inf - R0) / R0 on either measure
    lube            Lube et al. (2004, J. Fluid Mech. 508, eqs. 3.1-3.2, named before the runs):
                    (R_inf - R0) / R0 = 1.24 a for a < 1.7, 1.6 a^(1/2) above
    edge_vs_lube    spread_edge / lube - 1
    height_over_r0  H_inf / R0
    t_stop_s, t_stop_scaled   the first time after the peak of the kinetic energy at which it is
                    below 1e-3 of the peak, from the collapse's start (runout.csv's t_flow, after
                    a consolidation stage), and that time over sqrt(H0 / g) (empty: not reached)
    t_end_s         the run's last sample (the scene's duration, or earlier: at rest or stopped)
    at_rest_s       time.stop_at_rest's window start where the run ended at rest (run.txt)
    rest_end_s, edge_at_rest_end_m   a run without stop_at_rest: when stop_at_rest = 1e-4 with
                    rest_hold = 0.1 s would have ended it (the driver's rule, rest_since in
                    mpm/src/run/driver.cpp), and deposit.csv's edge then: its change to edge_m is
                    what ending at rest costs
"""
import csv
import math
import os
import re
import sys

G = 9.81


def lube(a):
    return 1.24 * a if a < 1.7 else 1.6 * math.sqrt(a)


def scene_value(text, key):
    m = re.search(r"^" + key + r" = (.+)$", text, re.M)
    return m.group(1).strip() if m else None


def numbers(v):
    return [float(x) for x in v.strip("[]").split(",")]


def map_edge(asc, x0, z0, threshold, plan):
    """The edge about (x0, z0) where the annuli's mean thickness falls below threshold, as
    granflow's deposit_edges (mpm/src/output/maps.cpp) on the cells whose centres lie in plan
    (x_lo, x_hi, z_lo, z_hi); the raster's origin is the grid's (make_cylinder_collapse.py)."""
    with open(asc) as f:
        head = {}
        for _ in range(6):
            k, v = f.readline().split()
            head[k.lower()] = float(v)
        ncols, nrows, cs = int(head["ncols"]), int(head["nrows"]), head["cellsize"]
        west, south = head["xllcorner"], head["yllcorner"]
        sum_r, sum_t, count = {}, {}, {}
        for row, line in enumerate(f):
            z = south + (nrows - 1 - row + 0.5) * cs
            if not plan[2] <= z <= plan[3]:
                continue
            for col, v in enumerate(line.split()):
                x = west + (col + 0.5) * cs
                if not plan[0] <= x <= plan[1]:
                    continue
                r = math.hypot(x - x0, z - z0)
                k = int(r / cs)
                sum_r[k] = sum_r.get(k, 0.0) + r
                sum_t[k] = sum_t.get(k, 0.0) + max(float(v), 0.0)
                count[k] = count.get(k, 0) + 1
    r_in = t_in = None
    for k in sorted(count):
        r, t = sum_r[k] / count[k], sum_t[k] / count[k]
        if t < threshold:
            return 0.0 if r_in is None else r_in + (r - r_in) * (t_in - threshold) / (t_in - t)
        r_in, t_in = r, t
    return float("nan")


def rest_since(rows, ratio, hold):
    """The driver's rest window (rows of (t, kinetic energy) of the one stage): its start, or None."""
    peak = max((e for _, e in rows), default=0.0)
    if not peak > 0:
        return None
    first = len(rows)
    while first > 0 and rows[first - 1][1] < ratio * peak:
        first -= 1
    if first == len(rows) or rows[-1][0] - rows[first][0] < hold - 1e-9:
        return None
    return rows[first][0]


def rest_end(ke, ratio=1e-4, hold=0.1):
    """When a run with time.stop_at_rest = ratio would have ended: at the sample after the one
    that completes the window (the driver checks the rows before the newest)."""
    for k in range(1, len(ke)):
        if rest_since(ke[:k], ratio, hold) is not None:
            return ke[k][0]
    return None


def last_row(path):
    rows = list(csv.DictReader(open(path)))
    return rows, rows[-1] if rows else None


def line_height(scene):
    """The height of runout.csv's reference line: [runout]'s y (level), else the grid's bottom."""
    m = re.search(r"^\[runout\]\s*\n(?:.*\n)*?y = (\[.*\])", scene, re.M)
    if m:
        ys = numbers(m.group(1))
        if max(ys) != min(ys):
            raise SystemExit("runout.y is not level: the height above the ground is not its offset")
        return ys[0]
    origin = scene_value(scene.split("[grid]", 1)[1], "origin")
    return numbers(origin)[1]


def summary(case):
    scene = open(os.path.join(case, "scene.toml")).read()
    head = scene.split("\n", 1)[0]
    m = re.search(r"a = ([0-9.eE+-]+), R0 = ([0-9.eE+-]+) m, h = ([0-9.eE+-]+) m", head)
    if not m:
        raise SystemExit(f"{case}/scene.toml: line 1 does not name a, R0 and h (not made by make_cylinder_collapse.py?)")
    a, r0, h = (float(v) for v in m.groups())
    name = os.path.basename(os.path.normpath(case))
    out = {"case": name, "a": a, "r0_m": r0, "h_mm": h * 1e3, "r0_over_h": round(r0 / h, 2),
           "variant": name.split("__", 1)[1] if "__" in name else "baseline"}
    ex = os.path.join(case, "exit")
    out["exit"] = open(ex).read().strip() if os.path.exists(ex) else "0"
    txt = os.path.join(case, "run.txt")
    if os.path.exists(txt):
        for line in open(txt):
            if line.startswith("steps:"):
                out["steps"] = line.split()[1]
            elif line.startswith("wall:"):
                out["wall_s"] = line.split()[1]
            elif "device time per step (spans)" in line:
                out["device_us_per_step"] = line.split()[5]
            elif line.startswith("at rest:"):
                out["at_rest_s"] = re.search(r"from t = ([0-9.eE+-]+) s", line).group(1)
    run = os.path.join(case, "run")
    ro = os.path.join(run, "runout.csv")
    if os.path.exists(ro):
        rows, last = last_row(ro)
        if last:
            out["runout_front_m"] = last["runout"]
            height = float(last["height"]) + line_height(scene)  # the ground is at y = 0
            out["height_m"] = round(height, 9)
            ke = [(float(r.get("t_flow", r["t"])), float(r["kinetic_energy"])) for r in rows]
            ke = [k for k in ke if k[0] >= 0]  # the collapse stage (not a consolidation before it)
            ipk = max(range(len(ke)), key=lambda i: ke[i][1])
            peak = ke[ipk][1]
            stop = next((t for t, e in ke[ipk:] if e < 1e-3 * peak), None)
            if stop is not None:
                out["t_stop_s"] = stop
                out["t_stop_scaled"] = round(stop / math.sqrt(a * r0 / G), 3)
            out["t_end_s"] = last["t"]
            end = rest_end(ke) if "at_rest_s" not in out else None
            if end is not None:
                out["rest_end_s"] = end
            front = float(last["runout"])
            out["spread_front"] = round((front - r0) / r0, 4)
            out["height_over_r0"] = round(height / r0, 4)
    dep = os.path.join(run, "deposit.csv")
    if os.path.exists(dep):
        rows_dep, last = last_row(dep)
        if last:
            out["edge_m"] = last["edge_radius"]
            out["edge_axes_m"] = last["edge_radius_axes"]
            out["edge_diagonals_m"] = last["edge_radius_diagonals"]
            out["spread_edge"] = round((float(last["edge_radius"]) - r0) / r0, 4)
            out["edge_vs_lube"] = round(out["spread_edge"] / lube(a) - 1, 4)
            if "rest_end_s" in out:
                out["edge_at_rest_end_m"] = next((r["edge_radius"] for r in rows_dep
                                                  if abs(float(r.get("t_flow", r["t"])) - out["rest_end_s"]) < 1e-9), "")
    ppc = int(scene_value(scene, "per_cell") or 8)
    spacing = h / round(ppc ** (1 / 3))
    et = scene_value(scene, "edge_thickness")
    out["edge_thickness_m"] = float(et) if et else spacing
    asc = os.path.join(run, "maps", "deposit_thickness.asc")
    centre = scene_value(scene, "deposit_centre")
    if os.path.exists(asc) and centre:
        org, size = numbers(scene_value(scene, "origin")), numbers(scene_value(scene, "size"))
        plan = (org[0], org[0] + size[0], org[2], org[2] + size[2])
        out["edge_spacing_m"] = round(map_edge(asc, *numbers(centre), spacing, plan), 6)
    out["lube"] = round(lube(a), 4)
    return out


COLS = ["case", "a", "r0_m", "h_mm", "r0_over_h", "variant", "exit", "steps", "wall_s", "device_us_per_step",
        "runout_front_m", "edge_m", "edge_axes_m", "edge_diagonals_m", "edge_thickness_m", "edge_spacing_m", "height_m", "spread_front", "spread_edge",
        "lube", "edge_vs_lube", "height_over_r0", "t_stop_s", "t_stop_scaled",
        "t_end_s", "at_rest_s", "rest_end_s", "edge_at_rest_end_m"]

if __name__ == "__main__":
    if len(sys.argv) < 2:
        raise SystemExit(__doc__)
    w = csv.DictWriter(sys.stdout, COLS, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for c in sys.argv[1:]:
        w.writerow(summary(c))
