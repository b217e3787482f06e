#!/usr/bin/env python3
"""PNG snapshots of an MPM output directory (granflow mpm ... --out DIR).

    python3 scripts/plot_mpm.py DIR [--fields p,T,eps_pd] [--frames all|last] [--spacing S]

Reads DIR/frames.pvd and the VTU frames it lists (raw appended binary, inline base64 or ASCII:
output.format), and writes DIR/png/<frame>_<field>.png plus DIR/png/runout.png from runout.csv and, where
the run measured forces, DIR/png/forces.png from obstacle_forces.csv (each obstacle's mean and
largest single-step force; every boundary's when the scene has no obstacle).
Fields: any scalar point array of the frames (p, q, eps_pd, T, eta_c, K_col, e, sigma_xx,
sigma_yy, sigma_xy) and speed (|velocity|). Every point is drawn as a square as wide as the
particle spacing (the lattice spacing of the first frame, or --spacing S in metres), so the body
looks continuous at any resolution; all frames of one call share the axes' limits. Each PNG is
written to a temporary name and renamed when complete.
Without matplotlib it prints a message and exits 0 (PNG output is optional).
"""
import argparse
import base64
import csv
import os
import struct
import sys
import xml.etree.ElementTree as ET

from png_output import save_png  # noqa: E402  (beside this script)

# Units of the point arrays (granflow's VTU writer, SI; docs/mpm.md "Outputs").
UNITS = {
    "p": "Pa", "q": "Pa", "sigma_xx": "Pa", "sigma_yy": "Pa", "sigma_xy": "Pa",
    "T": "m²/s²", "eta_c": "Pa s", "eps_pd": "-", "K_col": "-", "e": "-", "speed": "m/s",
}
# Fields spanning many decades are drawn on a logarithmic colour scale.
LOG_FIELDS = ("T", "eta_c")


def read_vtu(path, np):
    """Float64 point arrays of a granflow VTU frame: name -> array (components as rows).
    Arrays appended raw after the XML (output.format "binary"), inline base64 ("base64") or
    ASCII; each binary block starts with its byte count, a UInt32 or UInt64 (header_type)."""
    with open(path, "rb") as f:
        data = f.read()
    tag = b'<AppendedData encoding="raw">'
    at = data.find(tag)
    if at >= 0:  # the XML before the raw bytes, closed; they start after the '_'
        root = ET.fromstring(data[:at] + b"</VTKFile>")
        raw0 = data.index(b"_", at + len(tag)) + 1
    else:
        root = ET.fromstring(data)
        raw0 = None
    order = "<" if root.get("byte_order", "LittleEndian") == "LittleEndian" else ">"
    count = order + ("Q" if root.get("header_type") == "UInt64" else "I")
    csize = struct.calcsize(count)
    arrays = {}
    for da in root.iter("DataArray"):
        name, fmt, typ = da.get("Name"), da.get("format"), da.get("type")
        if typ != "Float64":
            continue
        ncomp = int(da.get("NumberOfComponents", "1"))
        if fmt == "ascii":
            vals = np.array((da.text or "").split(), dtype=float)
        elif fmt == "appended":
            start = raw0 + int(da.get("offset"))
            nbytes = struct.unpack(count, data[start:start + csize])[0]
            vals = np.frombuffer(data, dtype=order + "f8", count=nbytes // 8, offset=start + csize)
        else:
            raw = base64.b64decode((da.text or "").strip())
            nbytes = struct.unpack(count, raw[:csize])[0]
            vals = np.frombuffer(raw[csize:csize + nbytes], dtype=order + "f8")
        arrays[name] = vals.reshape(-1, ncomp).T if ncomp > 1 else vals
    if "velocity" in arrays:
        arrays["speed"] = np.sqrt((arrays["velocity"] ** 2).sum(axis=0))
    return arrays


def lattice_spacing(x, y, np):
    """Spacing of points seeded on a regular lattice (granflow seeds every body on one): the
    median gap between distinct coordinates along x and y. Falls back to the median
    nearest-neighbour distance of a sample when the points are not on a lattice."""
    gaps = []
    for c in (x, y):
        u = np.unique(np.round(c, 10))
        if 1 < len(u) < len(c):
            gaps.append(float(np.median(np.diff(u))))
    if gaps and min(gaps) > 0:
        return min(gaps)
    n = len(x)
    pick = np.random.default_rng(0).choice(n, size=min(n, 400), replace=False)
    nearest = []
    for i in pick:
        d2 = (x - x[i]) ** 2 + (y - y[i]) ** 2
        d2[i] = np.inf
        nearest.append(d2.min())
    return float(np.sqrt(np.median(nearest)))


def label(field):
    return "%s [%s]" % (field, UNITS.get(field, "?"))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dir")
    ap.add_argument("--fields", default="p,T,eps_pd")
    ap.add_argument("--frames", default="all", choices=["all", "last"])
    ap.add_argument("--spacing", type=float, default=0.0, help="particle spacing [m] (default: from the first frame)")
    a = ap.parse_args()
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.colors import LogNorm
        from mpl_toolkits.axes_grid1 import make_axes_locatable
        import numpy as np
    except ImportError:
        print("plot_mpm.py: matplotlib not available, PNG snapshots skipped")
        return 0
    pvd = os.path.join(a.dir, "frames.pvd")
    if not os.path.exists(pvd):
        print("plot_mpm.py: %s not found" % pvd, file=sys.stderr)
        return 1
    frames = [(float(d.get("timestep")), d.get("file")) for d in ET.parse(pvd).getroot().iter("DataSet")]
    if not frames:
        print("plot_mpm.py: %s lists no frame" % pvd, file=sys.stderr)
        return 1
    spacing = a.spacing
    if spacing <= 0:  # the first frame (t = 0) still holds the seeding lattice
        first = read_vtu(os.path.join(a.dir, frames[0][1]), np)
        spacing = lattice_spacing(first["position"][0], first["position"][1], np)
    if a.frames == "last":
        frames = frames[-1:]
    data = [(t, f, read_vtu(os.path.join(a.dir, f), np)) for t, f in frames]
    # one view for all frames: the union of their points plus a spacing
    xs = np.concatenate([arr["position"][0] for _, _, arr in data])
    ys = np.concatenate([arr["position"][1] for _, _, arr in data])
    xlim = (xs.min() - spacing, xs.max() + spacing)
    ylim = (ys.min() - spacing, ys.max() + spacing)
    aspect = (ylim[1] - ylim[0]) / (xlim[1] - xlim[0])
    # axes of at most 6 x 6 inches at the data's aspect, plus room for the colour bar and labels
    ax_w, ax_h = (6.0, 6.0 * aspect) if aspect <= 1 else (6.0 / aspect, 6.0)
    width, height = max(ax_w + 2.0, 4.5), max(ax_h + 1.1, 2.4)

    outdir = os.path.join(a.dir, "png")
    os.makedirs(outdir, exist_ok=True)
    fields = [f for f in a.fields.split(",") if f]
    written = 0
    for t, f, arr in data:
        x, y = arr["position"][0], arr["position"][1]
        for field in fields:
            if field not in arr or arr[field].ndim != 1:
                print("plot_mpm.py: field %s not in %s, skipped" % (field, f), file=sys.stderr)
                continue
            v = arr[field]
            norm = None
            pos = v[v > 0]
            if field in LOG_FIELDS and len(pos) and pos.max() > 1e3 * pos.min():
                norm = LogNorm(vmin=max(pos.min(), pos.max() * 1e-8), vmax=pos.max())
                v = np.clip(v, norm.vmin, None)
            fig, ax = plt.subplots(figsize=(width, height))
            sc = ax.scatter(x, y, c=v, s=1, marker="s", cmap="viridis", norm=norm, linewidths=0)
            ax.set_xlim(*xlim)
            ax.set_ylim(*ylim)
            ax.set_aspect("equal")
            cax = make_axes_locatable(ax).append_axes("right", size=0.2, pad=0.1)  # as tall as the axes
            fig.colorbar(sc, cax=cax, label=label(field), format=None if norm else "%.3g")  # no offset text
            ax.set_xlabel("x [m]")
            ax.set_ylabel("y [m]")
            ax.set_title("%s, t = %.4g s%s(%d points, spacing %.3g mm)"
                         % (field, t, " " if width > 6.5 else "\n", len(x), spacing * 1e3))
            fig.tight_layout()
            # marker side = particle spacing: data units -> display pixels -> points (area in
            # points^2); 10 % more, so that sub-pixel gaps between neighbours do not show as lines
            fig.canvas.draw()
            px = abs(ax.transData.transform((spacing, 0))[0] - ax.transData.transform((0, 0))[0])
            side = 1.1 * px * 72.0 / fig.dpi
            sc.set_sizes([side * side])
            save_png(fig, os.path.join(outdir, "%s_%s.png" % (os.path.splitext(f)[0], field)), 130)
            plt.close(fig)
            written += 1
    runout = os.path.join(a.dir, "runout.csv")
    if os.path.exists(runout):
        rows = [l.strip().split(",") for l in open(runout)][1:]
        t = [float(r[1]) for r in rows]
        fig, ax = plt.subplots(figsize=(6, 3.5))
        ax.plot(t, [float(r[3]) for r in rows], label="run-out")
        ax.plot(t, [float(r[4]) for r in rows], label="height")
        ax.set_xlabel("t_flow: time since the last stage began [s]")
        ax.set_ylabel("length [m]")
        ax.grid(alpha=0.3)
        ax.legend()
        fig.tight_layout()
        save_png(fig, os.path.join(outdir, "runout.png"), 130)
        plt.close(fig)
        written += 1
    forces = os.path.join(a.dir, "obstacle_forces.csv")
    if os.path.exists(forces):  # the force history of each obstacle (else of every boundary)
        with open(forces, newline="") as f:  # names may be quoted (commas, line breaks)
            lines = list(csv.reader(f))
        head, rows = lines[0], [r for r in lines[1:] if r[3] == "total"]
        col = {name.split(" [")[0]: k for k, name in enumerate(head)}
        unit = head[col["Fx"]].split("[")[1].rstrip("]")
        names = list(dict.fromkeys(r[2] for r in rows))
        shown = [n for n in names if not (n.startswith("wall[") or n in ("base", "terrain"))] or names
        fig, ax = plt.subplots(figsize=(6.5, 3.8))
        for n in shown:
            mine = [r for r in rows if r[2] == n]
            t = [float(r[col["t_flow"]]) for r in mine]
            comps = [c for c in ("Fx", "Fy", "Fz") if c in col]
            mean = [sum(float(r[col[c]]) ** 2 for c in comps) ** 0.5 for r in mine]
            line, = ax.plot(t, mean, label="%s: |mean force|" % n)
            ax.plot(t, [float(r[col["F_max"]]) for r in mine], ls="--", lw=0.8, color=line.get_color(),
                    label="%s: largest step force" % n)
        ax.set_xlabel("t_flow: time since the last stage began [s]")
        ax.set_ylabel("force [%s]" % unit)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        save_png(fig, os.path.join(outdir, "forces.png"), 130)
        plt.close(fig)
        written += 1
    print("plot_mpm.py: %d PNG files in %s" % (written, outdir))
    return 0


if __name__ == "__main__":
    sys.exit(main())
