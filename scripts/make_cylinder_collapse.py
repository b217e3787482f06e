#!/usr/bin/env python3
"""An axisymmetric column collapse as a granflow scene (issue 53; docs/mpm_results.md).

    python3 scripts/make_cylinder_collapse.py OUT_DIR [--a 2] [--r0 0.1] [--h 0.004]
        [--set column_collapse] [--model phase_transition|frictional] [--full] [--vertices 49]
        [--ppc 8] [--dt DT] [--duration 1.2] [--precision fp32|mixed|fp64]
        [--scene scene.toml] [--rasters SUBDIR] [--spread S] [--gate-lift-speed V [--consolidation 0.1]]
        [--far-walls none|no_slip]

Writes OUT_DIR/scene.toml (--scene) and its flat rasters (ground.asc, top.asc, in OUT_DIR or
its --rasters subfolder): a cylinder of radius R0 and
height H0 = a R0 as a release volume on a level raster, no-slip ground, geostatic start,
`duration` seconds of collapse. A quarter cylinder with free-slip symmetry walls at x = 0 and z = 0
(the default), or with --full the whole cylinder at the grid's plan centre. The plan is a polygon
of `vertices` vertices on the circle (a quarter: from the x axis to the z axis); its area is below
the circle's by 1 - sin(dth)/dth (dth the angle between vertices), printed with the run-out
lengths the grid needs. deposit.csv gains `edge_radius` about the axis (output.deposit_centre).
The run-out of runout.csv is along x on the symmetry plane, its height above the ground ([runout] at y = 0).

With --gate-lift-speed V the start is not geostatic: the column consolidates from zero stress
for --consolidation seconds (local damping 0.5, as the paper's 2D scenes) inside a cylindrical
gate of radius R0 holding the radial velocity, and the collapse stage lifts that gate from the
ground at V m/s (V = 0: the gate is removed at once). Output times count from the start of the collapse.
"""
import argparse
import math
import os

p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
p.add_argument("out")
p.add_argument("--a", type=float, default=2.0, help="aspect ratio H0 / R0")
p.add_argument("--r0", type=float, default=0.1, help="radius R0 [m]")
p.add_argument("--h", type=float, default=0.004, help="grid spacing [m]")
p.add_argument("--set", default="column_collapse", help="parameter set (data/params name or file)")
p.add_argument("--model", default="phase_transition", choices=["phase_transition", "frictional"])
p.add_argument("--full", action="store_true", help="the whole cylinder (default: a quarter with symmetry walls)")
p.add_argument("--vertices", type=int, default=49, help="polygon vertices of the plan (a quarter: on the arc)")
p.add_argument("--ppc", type=int, default=8, help="points per cell (n^3)")
p.add_argument("--dt", type=float, default=0.0, help="time step [s] (default: 2.5e-3 h, the paper's 1e-5 s at 4 mm)")
p.add_argument("--duration", type=float, default=1.2, help="collapse time [s]")
p.add_argument("--edge-thickness", type=float, default=0.04,
               help="output.edge_thickness over R0: deposit.csv's edge is read at this thickness (default 0.04, the point spacing at R0/h = 12.5; 0: one point spacing, which shrinks with h)")
p.add_argument("--stop-at-rest", type=float, default=0.0,
               help="time.stop_at_rest: end once the kinetic energy stays below this fraction of its peak (0: run the whole duration)")
p.add_argument("--rest-hold", type=float, default=0.1, help="time.rest_hold [s], with --stop-at-rest")
p.add_argument("--precision", default="fp32", choices=["fp64", "mixed", "fp32"])
p.add_argument("--scene", default="scene.toml", help="the scene file's name in OUT_DIR")
p.add_argument("--rasters", default="", help="a subfolder of OUT_DIR for the rasters")
p.add_argument("--spread", type=float, default=0.0,
               help="the largest (R - R0) / R0 the grid must hold (default: three times Lube et al. 2004's law, 1.24 a below a = 1.7, 1.6 a^0.5 above: at a = 4 and R0/h = 25 the front passed twice the law)")
p.add_argument("--gate-lift-speed", type=float, default=None,
               help="consolidate behind a cylindrical gate (radius R0), then lift it at this speed [m/s] (0: removed at once)")
p.add_argument("--consolidation", type=float, default=0.1, help="the consolidation stage's duration [s], with --gate-lift-speed")
p.add_argument("--far-walls", default="none", choices=["none", "no_slip"],
               help="walls at the grid's far sides (x+, z+; and x-, z- with --full): no_slip stops the lone fringe "
                    "points that slide over the no-slip ground at about 1 m/s and would leave the grid (mpm_results.md)")
a = p.parse_args()

R0, H0, h = a.r0, a.a * a.r0, a.h
if R0 <= 0 or H0 <= 0 or h <= 0 or a.vertices < 3:
    p.error("R0, a, h must be positive and vertices at least 3")
gated = a.gate_lift_speed is not None
if gated and (a.gate_lift_speed < 0 or a.consolidation <= 0):
    p.error("--gate-lift-speed must be >= 0 and --consolidation positive")
spread = a.spread if a.spread > 0 else 3 * (1.24 * a.a if a.a < 1.7 else 1.6 * math.sqrt(a.a))
reach = R0 * (1 + spread)                          # largest radius the grid holds
side = math.ceil((reach + 2 * h) / h) * h         # plan size from the axis
Ly = math.ceil((H0 + 3 * h) / h) * h
dt = a.dt if a.dt > 0 else 2.5e-3 * h
rdir = os.path.join(a.out, a.rasters) if a.rasters else a.out
os.makedirs(rdir, exist_ok=True)
rel = (a.rasters.rstrip("/") + "/") if a.rasters else ""

# level rasters in scene coordinates (easting = x, northing = z, elevation = y): cells of h / 2
cell = h / 2
if a.full:
    size_x = size_z = 2 * side
    cx = cz = side
else:
    size_x = size_z = side
    cx = cz = 0.0
n = int(math.ceil(size_x / cell)) + 2


def raster(path, elevation):
    with open(path, "w") as f:
        f.write(f"ncols {n}\nnrows {n}\nxllcorner {-cell:.6f}\nyllcorner {-cell:.6f}\ncellsize {cell:.6f}\n")
        row = " ".join(f"{elevation:.6f}" for _ in range(n))
        for _ in range(n):
            f.write(row + "\n")


raster(os.path.join(rdir, "ground.asc"), 0.0)
raster(os.path.join(rdir, "top.asc"), H0)

if a.full:
    k = a.vertices
    th = [2 * math.pi * i / k for i in range(k)]
    xs = [cx + R0 * math.cos(t) for t in th]
    zs = [cz + R0 * math.sin(t) for t in th]
    dth = 2 * math.pi / k
    area_ratio = math.sin(dth) / dth
else:  # the arc's vertices and the axis
    k = a.vertices
    th = [0.5 * math.pi * i / (k - 1) for i in range(k)]
    xs = [R0 * math.cos(t) for t in th] + [0.0]
    zs = [R0 * math.sin(t) for t in th] + [0.0]
    xs[k - 1] = 0.0  # exactly on the symmetry walls
    zs[0] = 0.0
    dth = 0.5 * math.pi / (k - 1)
    area_ratio = math.sin(dth) / dth

fmt = lambda v: ", ".join(f"{x:.9g}" for x in v)
model = "phase_transition" if a.model == "phase_transition" else "frictional"
lines = [
    f"# Axisymmetric collapse, a = {a.a:g}, R0 = {R0:g} m, h = {h:g} m (R0/h = {R0 / h:g}); "
    f"made by scripts/make_cylinder_collapse.py",
    f'name = "cylinder collapse a {a.a:g}, R0/h {R0 / h:g}, {"full" if a.full else "quarter"}, {a.set}"',
    "", "[grid]", "dim = 3", f"origin = [0.0, {-2 * h:.9g}, 0.0]", f"size = [{size_x:.9g}, {Ly + 2 * h:.9g}, {size_z:.9g}]",
    f"h = {h:g}", 'shape = "quadratic"', "", "[particles]", f"per_cell = {a.ppc}", "", "[time]", f"dt = {dt:.6g}"] + (
    [f"stop_at_rest = {a.stop_at_rest:g}", f"rest_hold = {a.rest_hold:g}"] if a.stop_at_rest > 0 else []) + ["",
    "[solver]", "gravity = [0.0, -9.81, 0.0]", 'transfer = "tpic"', "pic_speed = 1.0", f'precision = "{a.precision}"', "",
    "[material]", f'parameters = "{a.set}"', f'model = "{model}"', ""] + (
    [] if gated else ["[initial_stress]", 'kind = "geostatic"', ""]) + [
    "[terrain]", f'file = "{rel}ground.asc"', "origin = [0.0, 0.0, 0.0]", "",
    "[[body]]", f'top = "{rel}top.asc"', f"plan_x = [{fmt(xs)}]", f"plan_z = [{fmt(zs)}]", "",
]
if not a.full:
    lines += ["[[wall]]", 'side = "x-"', 'type = "free_slip"', "", "[[wall]]", 'side = "z-"', 'type = "free_slip"', ""]
if a.far_walls != "none":
    for side_name in ["x+", "z+"] + (["x-", "z-"] if a.full else []):
        lines += ["[[wall]]", f'side = "{side_name}"', f'type = "{a.far_walls}"', ""]
gate = ["[stage.gate]", f"point = [{cx:.9g}, 0.0, {cz:.9g}]", f"radius = {R0:.9g}", 'hold = "normal"']
if gated:
    lines += ["[[stage]]", 'name = "consolidation"', f"duration = {a.consolidation:g}", "damping = 0.5"] + gate + [""]
lines += ["[[stage]]", 'name = "collapse"', f"duration = {a.duration:g}"]
if gated and a.gate_lift_speed > 0:
    lines += gate + [f"lift_speed = {a.gate_lift_speed:g}"]
# runout.csv along x on the ground (y = 0): its height is then above the ground, not above the
# grid's bottom at -2 h (the default line)
lines += ["", "[runout]", f"x = [0.0, {size_x:.9g}]", "y = [0.0, 0.0]"]
lines += ["", "[output]", "series_dt = 0.01", f"times = [{a.duration:g}]", f"deposit_centre = [{cx:.9g}, {cz:.9g}]"]
if a.edge_thickness > 0:
    lines += [f"edge_thickness = {a.edge_thickness * R0:.9g}"]
lines += [""]
with open(os.path.join(a.out, a.scene), "w") as f:
    f.write("\n".join(lines))
print(f"{os.path.join(a.out, a.scene)}: a = {a.a:g}, R0 = {R0:g} m, H0 = {H0:g} m, h = {h:g} m, dt = {dt:g} s; "
      f"plan {'full' if a.full else 'quarter'} of {a.vertices} vertices: its area is {100 * (1 - area_ratio):.3f} % "
      f"below the circle's; the grid holds R up to {reach:.3g} m ((R - R0)/R0 = {spread:.2f})")
