#!/usr/bin/env python3
"""The 3D stability matrix of docs/mpm_results.md (issue 52): a 10 x 10 x 4 cm block sliding with
Coulomb friction mu 0.3 on a 30 deg ground, run to its end or to where it stops.

    python3 scripts/stability_matrix_3d.py --granflow build/granflow --out out/stability3d \
        [--h 20 10 5] [--shape linear quadratic] [--phi 30 50 70] [--init zero geostatic] \
        [--ground level slope wall] [--backend cpu|cuda] [--duration 0.3] [--set KEY=VALUE ...]

Axes: shape; h [mm]; phi_c [deg] (the flume set, frictional model); initial stress (zero with a
0.1 s damped consolidation, or geostatic); ground: a level raster with gravity tilted 30 deg
along x, a raster dipping 30 deg along x with vertical gravity, or a frictional y- wall with the
tilted gravity. 8 points per cell, dt 1e-4 s (5e-5 at 5 mm). Writes one scene per cell, runs
granflow mpm on it, and appends a row to OUT/matrix.csv: the cell, ran (1/0), the time reached,
the message of a stopped run, wall seconds, and the steps the cap at the stable step shortened
(time.cap_to_stable; "time.dt: N steps shortened" in granflow's output) with the shortest.
"""
import argparse
import csv
import math
import os
import re
import subprocess
import time

p = argparse.ArgumentParser()
p.add_argument("--granflow", default="build/granflow")
p.add_argument("--out", default="out/stability3d")
p.add_argument("--h", nargs="+", type=float, default=[20, 10, 5])
p.add_argument("--shape", nargs="+", default=["linear", "quadratic"])
p.add_argument("--phi", nargs="+", type=float, default=[30, 50, 70])
p.add_argument("--init", nargs="+", default=["zero", "geostatic"])
p.add_argument("--ground", nargs="+", default=["level", "slope", "wall"])
p.add_argument("--backend", default="cpu")
p.add_argument("--duration", type=float, default=0.3)
p.add_argument("--offset", type=float, default=0.013, help="the raster ground's height above a node row [m]")
p.add_argument("--timeout", type=float, default=1800)
p.add_argument("--set", action="append", default=[], help="more --set KEY=VALUE for every run (e.g. terrain.contact=nodes)")
a = p.parse_args()
os.makedirs(a.out, exist_ok=True)

TH = math.radians(30.0)
L, W, T = 0.10, 0.10, 0.04          # block along the dip, across, thick
SX, SZ = 0.50, 0.16                  # footprint
G = 9.81


def raster(path, f, cell=0.01, west=-0.05, south=-0.05, nc=61, nr=26):
    with open(path, "w") as o:
        o.write(f"ncols {nc}\nnrows {nr}\nxllcorner {west}\nyllcorner {south}\ncellsize {cell}\n")
        for r in range(nr):
            o.write(" ".join(f"{f(west + (c + 0.5) * cell):.6f}" for c in range(nc)) + "\n")


def scene(h, shape, phi, init, ground):
    name = f"{shape}_h{h:g}_phi{phi:g}_{init}_{ground}"
    d = os.path.join(a.out, name)
    os.makedirs(d, exist_ok=True)
    hm = h / 1000.0
    dt = 1e-4 if h >= 10 else 5e-5
    tilted = ground != "slope"
    grav = [G * math.sin(TH), -G * math.cos(TH), 0.0] if tilted else [0.0, -G, 0.0]
    off = a.offset  # the ground off the node rows (raster grounds)
    lines = [f'name = "stability {name}"', "[grid]", "dim = 3", "origin = [0.0, 0.0, 0.0]"]
    if ground == "slope":
        H = off + math.tan(TH) * (SX + 0.05) + 2 * hm
        sy = math.ceil((H + T / math.cos(TH) + 0.05) / hm) * hm
    else:
        H = off + 2 * hm
        sy = math.ceil((H + T + 0.05) / hm) * hm
    lines += [f"size = [{SX}, {sy:.4f}, {SZ}]", f"h = {hm}", f'shape = "{shape}"', "[particles]", "per_cell = 8",
              "[time]", f"dt = {dt}", "[solver]", f"gravity = [{grav[0]:.6f}, {grav[1]:.6f}, 0.0]",
              "[material]", 'parameters = "flume"', 'model = "frictional"', "[initial_stress]", f'kind = "{init}"']
    x0, x1, z0, z1 = 0.03, 0.03 + L, 0.03, 0.03 + W
    if ground == "wall":
        lines += ["[[wall]]", 'side = "y-"', 'type = "frictional"', "mu = 0.3",
                  "[[body]]", f"min = [{x0}, 0.0, {z0}]", f"max = [{x1}, {T}, {z1}]"]
    else:
        slope = math.tan(TH) if ground == "slope" else 0.0
        raster(os.path.join(d, "ground.asc"), lambda x: -slope * x)
        raster(os.path.join(d, "top.asc"), lambda x: -slope * x + (T / math.cos(TH) if ground == "slope" else T))
        lines += ["[terrain]", 'file = "ground.asc"', f"origin = [0.0, 0.0, {-H:.6f}]", "mu = 0.3",
                  "[[body]]", 'top = "top.asc"', f"plan_x = [{x0}, {x1}, {x1}, {x0}]", f"plan_z = [{z0}, {z0}, {z1}, {z1}]"]
    lines += ["[[wall]]", 'side = "z-"', 'type = "free_slip"', "[[wall]]", 'side = "z+"', 'type = "free_slip"']
    if init == "zero":
        lines += ["[[stage]]", 'name = "consolidation"', "duration = 0.1", "damping = 0.5"]
    lines += ["[[stage]]", 'name = "slide"', f"duration = {a.duration}", "[output]", "series_dt = 0.01", f"times = [{a.duration}]"]
    path = os.path.join(d, "scene.toml")
    with open(path, "w") as o:
        o.write("\n".join(lines) + "\n")
    return name, path, d


rows_path = os.path.join(a.out, "matrix.csv")
new = not os.path.exists(rows_path)
with open(rows_path, "a", newline="") as f:
    w = csv.writer(f)
    if new:
        w.writerow(["shape", "h_mm", "phi_c_deg", "initial", "ground", "ran", "t_reached", "message", "wall_s",
                    "shortened", "dt_min_s"])
    for h in a.h:
        for shape in a.shape:
            for phi in a.phi:
                for init in a.init:
                    for ground in a.ground:
                        name, path, d = scene(h, shape, phi, init, ground)
                        cmd = [a.granflow, "mpm", path, "--out", os.path.join(d, "run"), "--force", "--no-png",
                               "--backend", a.backend, "--set", f"frictional.phi_c_deg={phi}"]
                        for kv in a.set:
                            if ground != "wall" or not kv.startswith("terrain."):
                                cmd += ["--set", kv]
                        t0 = time.time()
                        try:
                            r = subprocess.run(cmd, capture_output=True, text=True, timeout=a.timeout)
                            out, rc = r.stdout + r.stderr, r.returncode
                        except subprocess.TimeoutExpired:
                            out, rc = "timeout", -1
                        wall = time.time() - t0
                        t_end = 0.0
                        rp = os.path.join(d, "run", "runout.csv")
                        if os.path.exists(rp):
                            with open(rp) as g:
                                last = list(csv.reader(g))[-1]
                                try:
                                    t_end = float(last[0])
                                except ValueError:
                                    pass
                        msg = ""
                        if rc != 0:
                            msg = next((l.strip() for l in out.splitlines() if "bad" in l or "error" in l.lower()), out.strip()[-200:])
                        m = re.search(r"time.dt: (\d+) steps shortened.*the shortest ([0-9.e+-]+) s", out)
                        short, dt_min = (m.group(1), m.group(2)) if m else ("0", "")
                        w.writerow([shape, h, phi, init, ground, int(rc == 0), f"{t_end:g}", msg, f"{wall:.1f}", short, dt_min])
                        f.flush()
                        print(f"{name}: {'ran' if rc == 0 else 'STOPPED'} t {t_end:g} s ({wall:.1f} s) {msg[:160]}", flush=True)
