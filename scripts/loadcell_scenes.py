#!/usr/bin/env python3
"""Write the load-cell flume scenes (mpm/scenes/loadcell/): Moriguchi et al. (2009)'s flume
with a rigid wall at the end of the slope, for slope angles 45-65 deg (docs/mpm_results.md).

  scripts/loadcell_scenes.py [--h 0.005] [--angles 45 50 55 60 65] [--out mpm/scenes/loadcell]

The experiment's sizes this scene takes from MODEL.md section 12: the slope 2.30 m long, the
box 50 cm along it and 30 cm normal to it at its top (vertical end faces, as flume.toml). The
assumptions (sizes not found in a public source) are named in ASSUMED below and in each file.
"""
import argparse
import math
import os

SLOPE_LENGTH = 2.30        # m, along the slope (MODEL.md 12)
BOX_ALONG, BOX_NORMAL = 0.50, 0.30   # m (MODEL.md 12)
ASSUMED = {
    "wall_height": 0.10,   # m, normal to the slope: the load cell's plate height
    "wall_thickness": 0.02,  # m: rigid; at least two cells of the finest grid run (5 mm)
    "wall_position": 0.0,  # m upstream of the slope's lower end: the wall stands at its end
    "floor_beyond": 1.00,  # m of horizontal floor past the slope's end to catch what overtops
}
APPROACH = 0.10  # m upstream of the wall: the approach gauge, beyond the wall's dead zone at impact


def scene(angle_deg, h, flow_s, name_note=""):
    a = math.radians(angle_deg)
    c, s = math.cos(a), math.sin(a)
    top_y = SLOPE_LENGTH * s
    foot_x = SLOPE_LENGTH * c
    t = (c, -s)            # down the slope
    n = (s, c)             # normal to the slope, out of it
    # wall: upstream face normal to the slope from its lower end, thickness downstream
    s_face = SLOPE_LENGTH - ASSUMED["wall_position"]
    face = (s_face * c, top_y - s_face * s)
    half = ASSUMED["wall_thickness"] / 2
    w_from = (face[0] + half * t[0], face[1] + half * t[1])
    w_to = (w_from[0] + ASSUMED["wall_height"] * n[0], w_from[1] + ASSUMED["wall_height"] * n[1])
    # gauge: a line normal to the slope two grid cells upstream of the wall's face
    g_s = s_face - 2 * h
    g_from = (g_s * c, top_y - g_s * s)
    g_to = (g_from[0] + 0.25 * n[0], g_from[1] + 0.25 * n[1])
    a_s = s_face - APPROACH
    a_from = (a_s * c, top_y - a_s * s)
    a_to = (a_from[0] + 0.25 * n[0], a_from[1] + 0.25 * n[1])
    box_x = BOX_ALONG * c
    box_h = BOX_NORMAL / c           # vertical height of the box's end faces
    size_x = foot_x + ASSUMED["floor_beyond"]
    size_y = math.ceil((top_y + box_h + 0.05) / h) * h
    size_x = math.ceil(size_x / h) * h
    f = lambda v: f"{v:.5f}"
    pt = lambda p: f"[{f(p[0])}, {f(p[1])}]"
    return f"""# Load-cell flume at {angle_deg} deg (written by scripts/loadcell_scenes.py; docs/mpm_results.md).
# Moriguchi et al. (2009)'s flume: a {SLOPE_LENGTH:.2f} m slope at {angle_deg} deg, the box at its top, and a rigid
# wall (the load cell) normal to the slope at its lower end, low enough to be overtopped.
# Assumed (not found in a public source): wall height {ASSUMED['wall_height']:.2f} m normal to the slope,
# thickness {ASSUMED['wall_thickness']:.2f} m, its upstream face at the slope's lower end, a horizontal floor
# {ASSUMED['floor_beyond']:.2f} m long beyond it. Frictional-only twin: --set material.model=frictional.
name = "load-cell flume {angle_deg} deg ({h * 1000:g} mm{name_note}), phase transition"

[grid]
origin = [0.0, 0.0]
size = [{f(size_x)}, {f(size_y)}]
h = {h:g}
shape = "quadratic"

[particles]
per_cell = 4

[time]            # CFL step (dt the largest)
dt = 1e-4
adaptive = true
cfl = 0.5

[solver]
transfer = "tpic"
pic_speed = 1.0

[material]
parameters = "flume"
model = "phase_transition"
e0 = 0.90
T0 = 1e-15

[[body]]          # the box: {BOX_ALONG:.2f} m along the slope, {BOX_NORMAL:.2f} m normal to it, vertical end faces
polygon_x = [0.0, {f(box_x)}, {f(box_x)}, 0.0]
polygon_y = [{f(top_y)}, {f(top_y - box_x * math.tan(a))}, {f(top_y - box_x * math.tan(a) + box_h)}, {f(top_y + box_h)}]

[[wall]]          # back wall of the box
side = "x-"
type = "free_slip"

[[wall]]
side = "x+"
type = "free_slip"

[base]            # no-slip slope, then the floor
x = [0.0, {f(foot_x)}, {f(size_x)}]
y = [{f(top_y)}, 0.0, 0.0]

[[stage]]
name = "consolidation"
duration = 0.1
damping = 0.5
[stage.gate]
point = [{f(box_x)}, 0.0]
normal = [1.0, 0.0]
hold = "normal"

[[stage]]
name = "flow"
duration = {flow_s:g}

[runout]
x = [0.0, {f(foot_x)}, {f(size_x)}]
y = [{f(top_y)}, 0.0, 0.0]

[[obstacle]]      # the load cell: moments about the foot of its upstream face
name = "load cell"
kind = "segment"
from = {pt(w_from)}
to = {pt(w_to)}
thickness = {ASSUMED['wall_thickness']:g}
moment_point = {pt(face)}

[[gauge]]         # two cells upstream of the wall: depth and velocity of the oncoming flow
name = "upstream"
from = {pt(g_from)}
to = {pt(g_to)}

[[gauge]]         # {APPROACH:.2f} m upstream: the flow before the wall slows it
name = "approach"
from = {pt(a_from)}
to = {pt(a_to)}

[output]
times = [0.5, 1.0, {flow_s:g}]
series_dt = 0.001
format = "binary"
"""


def main():
    global SLOPE_LENGTH, BOX_ALONG, BOX_NORMAL
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--h", type=float, default=0.005, help="grid spacing [m]")
    ap.add_argument("--angles", type=int, nargs="+", default=[45, 50, 55, 60, 65])
    ap.add_argument("--flow", type=float, default=2.0, help="seconds of flow after the gate opens")
    ap.add_argument("--out", default="mpm/scenes/loadcell")
    ap.add_argument("--thickness", type=float, default=ASSUMED["wall_thickness"],
                    help="wall thickness [m]: at least two grid cells")
    ap.add_argument("--suffix", default="", help="appended to the file names")
    ap.add_argument("--slope", type=float, default=SLOPE_LENGTH, help="slope length [m]")
    ap.add_argument("--box", type=float, nargs=2, default=[BOX_ALONG, BOX_NORMAL], metavar=("ALONG", "NORMAL"),
                    help="the box's sizes along and normal to the slope [m]")
    ap.add_argument("--wall-height", type=float, default=ASSUMED["wall_height"], help="normal to the slope [m]")
    a = ap.parse_args()
    SLOPE_LENGTH, (BOX_ALONG, BOX_NORMAL) = a.slope, a.box
    ASSUMED["wall_height"] = a.wall_height
    ASSUMED["wall_thickness"] = a.thickness
    os.makedirs(a.out, exist_ok=True)
    for ang in a.angles:
        path = os.path.join(a.out, f"loadcell_{ang}{a.suffix}.toml")
        with open(path, "w") as fh:
            small = a.slope != 2.30 or a.box != [0.50, 0.30]
            fh.write(scene(ang, a.h, a.flow, ", scaled down" if small else ""))
        print(path)


if __name__ == "__main__":
    main()
