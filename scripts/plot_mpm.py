#!/usr/bin/env python3
"""PNG snapshots of an MPM output directory (granflow mpm ... --out DIR).

    python3 scripts/plot_mpm.py DIR [--fields p,T,eps_pd] [--frames all|last]

Reads DIR/frames.pvd and the VTU frames it lists (base64 "binary" or ASCII, as granflow writes
them), and writes DIR/png/<frame>_<field>.png plus DIR/png/runout.png from runout.csv.
Without matplotlib it prints a message and exits 0 (PNG output is optional).
"""
import argparse
import base64
import os
import re
import struct
import sys
import xml.etree.ElementTree as ET


def read_vtu(path):
    root = ET.parse(path).getroot()
    arrays = {}
    for da in root.iter("DataArray"):
        name, fmt, typ = da.get("Name"), da.get("format"), da.get("type")
        ncomp = int(da.get("NumberOfComponents", "1"))
        text = (da.text or "").strip()
        if typ != "Float64":
            continue
        if fmt == "ascii":
            vals = [float(v) for v in text.split()]
        else:
            raw = base64.b64decode(text)
            nbytes = struct.unpack("<I", raw[:4])[0]
            vals = list(struct.unpack("<%dd" % (nbytes // 8), raw[4:4 + nbytes]))
        if ncomp > 1:
            vals = [vals[i::ncomp] for i in range(ncomp)]
        arrays[name] = vals
    return arrays


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dir")
    ap.add_argument("--fields", default="p,T,eps_pd")
    ap.add_argument("--frames", default="all", choices=["all", "last"])
    a = ap.parse_args()
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("plot_mpm.py: matplotlib not available, PNG snapshots skipped")
        return 0
    pvd = os.path.join(a.dir, "frames.pvd")
    if not os.path.exists(pvd):
        print("plot_mpm.py: %s not found" % pvd, file=sys.stderr)
        return 1
    frames = [(float(d.get("timestep")), d.get("file")) for d in ET.parse(pvd).getroot().iter("DataSet")]
    if a.frames == "last":
        frames = frames[-1:]
    outdir = os.path.join(a.dir, "png")
    os.makedirs(outdir, exist_ok=True)
    fields = [f for f in a.fields.split(",") if f]
    written = 0
    for t, f in frames:
        arr = read_vtu(os.path.join(a.dir, f))
        x, y = arr["position"][0], arr["position"][1]
        for field in fields:
            if field not in arr:
                print("plot_mpm.py: field %s not in %s, skipped" % (field, f), file=sys.stderr)
                continue
            fig, ax = plt.subplots(figsize=(8, 3.2))
            sc = ax.scatter(x, y, c=arr[field], s=2, cmap="viridis", linewidths=0)
            fig.colorbar(sc, ax=ax, label=field)
            ax.set_aspect("equal")
            ax.set_xlabel("x [m]")
            ax.set_ylabel("y [m]")
            ax.set_title("%s, t = %.4g s" % (field, t))
            fig.tight_layout()
            fig.savefig(os.path.join(outdir, "%s_%s.png" % (os.path.splitext(f)[0], field)), dpi=130)
            plt.close(fig)
            written += 1
    csv = os.path.join(a.dir, "runout.csv")
    if os.path.exists(csv):
        rows = [l.strip().split(",") for l in open(csv)][1:]
        t = [float(r[1]) for r in rows]
        fig, ax = plt.subplots(figsize=(6, 3.5))
        ax.plot(t, [float(r[3]) for r in rows], label="run-out")
        ax.plot(t, [float(r[4]) for r in rows], label="height")
        ax.set_xlabel("time since release [s]")
        ax.set_ylabel("[m]")
        ax.legend()
        fig.tight_layout()
        fig.savefig(os.path.join(outdir, "runout.png"), dpi=130)
        plt.close(fig)
        written += 1
    print("plot_mpm.py: %d PNG files in %s" % (written, outdir))
    return 0


if __name__ == "__main__":
    sys.exit(main())
