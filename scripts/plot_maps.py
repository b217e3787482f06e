#!/usr/bin/env python3
"""PNGs of the maps of a 3D terrain run (granflow mpm ... --out DIR, a scene with [terrain]).

    python3 scripts/plot_maps.py DIR

Reads DIR/maps/terrain.asc and the maps beside it (deposit_thickness, max_speed, max_depth; ESRI
ASCII grids as granflow writes them) and writes DIR/png/map_<name>.png: the map over a hillshade
of the terrain, cropped to the grid's footprint (the cells with values), cells of 0 left clear.
Each PNG is written to a temporary name and renamed when complete.
Without matplotlib it prints a message and exits 0 (PNG output is optional).
"""
import os
import sys

from png_output import save_png  # noqa: E402  (beside this script)

MAPS = (("deposit_thickness", "deposit thickness [m]"), ("max_speed", "largest speed [m/s]"),
        ("max_depth", "largest flow depth [m]"))


def read_asc(path, np):
    """(values with NaN for NODATA, row 0 the northern; west, south, cellsize)."""
    head, rows = {}, []
    with open(path) as f:
        for line in f:
            w = line.split()
            if not w:
                continue
            if w[0][0].isalpha():
                head[w[0].lower()] = float(w[1])
            else:
                rows.extend(float(v) for v in w)
    nc, nr, cs = int(head["ncols"]), int(head["nrows"]), head["cellsize"]
    west = head.get("xllcorner", head.get("xllcenter", 0.0) - 0.5 * cs)
    south = head.get("yllcorner", head.get("yllcenter", 0.0) - 0.5 * cs)
    v = np.array(rows, dtype=float).reshape(nr, nc)
    if "nodata_value" in head:
        v[np.isclose(v, head["nodata_value"], rtol=1e-6, atol=0)] = np.nan
    return v, west, south, cs


def main():
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    out = sys.argv[1]
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.colors import LightSource
        import numpy as np
    except ImportError:
        print("plot_maps.py: matplotlib not available, map PNGs skipped")
        return 0
    folder = os.path.join(out, "maps")
    terrain_path = os.path.join(folder, "terrain.asc")
    if not os.path.exists(terrain_path):
        print("plot_maps.py: %s not found" % terrain_path, file=sys.stderr)
        return 1
    z, west, south, cs = read_asc(terrain_path, np)
    ok = np.isfinite(z)
    if not ok.any():
        print("plot_maps.py: %s has no values" % terrain_path, file=sys.stderr)
        return 1
    rows, cols = np.where(ok)
    r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
    zc = z[r0:r1, c0:c1]
    north = south + z.shape[0] * cs
    extent = (west + c0 * cs, west + c1 * cs, north - r1 * cs, north - r0 * cs)
    shade = LightSource(azdeg=315, altdeg=45).hillshade(np.where(np.isfinite(zc), zc, np.nanmean(zc)), dx=cs, dy=cs)
    outdir = os.path.join(out, "png")
    os.makedirs(outdir, exist_ok=True)
    written = 0
    for name, label in MAPS:
        path = os.path.join(folder, name + ".asc")
        if not os.path.exists(path):
            continue
        v = read_asc(path, np)[0][r0:r1, c0:c1]
        w, h = extent[1] - extent[0], extent[3] - extent[2]
        aspect = h / w if w > 0 else 1.0
        ax_w, ax_h = (6.0, 6.0 * aspect) if aspect <= 1 else (6.0 / aspect, 6.0)
        fig, ax = plt.subplots(figsize=(max(ax_w + 2.0, 4.5), max(ax_h + 1.1, 2.4)))
        ax.imshow(shade, cmap="gray", extent=extent, origin="upper", vmin=0, vmax=1, interpolation="nearest")
        shown = np.ma.masked_where(~(v > 0), v)  # NODATA and empty cells leave the hillshade clear
        vmax = float(np.nanmax(v)) if np.isfinite(v).any() and np.nanmax(v) > 0 else 1.0
        im = ax.imshow(shown, cmap="viridis", extent=extent, origin="upper", vmin=0, vmax=vmax, alpha=0.85,
                       interpolation="nearest")
        fig.colorbar(im, ax=ax, label=label, format="%.3g")
        ax.set_xlabel("easting [m]")
        ax.set_ylabel("northing [m]")
        ax.ticklabel_format(useOffset=False, style="plain")
        ax.locator_params(axis="x", nbins=4)  # georeferenced eastings are long labels
        ax.set_title("%s (cells of %.3g m)" % (name, cs))
        fig.tight_layout()
        save_png(fig, os.path.join(outdir, "map_%s.png" % name), 130)
        plt.close(fig)
        written += 1
    print("plot_maps.py: %d PNG files in %s" % (written, outdir))
    return 0


if __name__ == "__main__":
    sys.exit(main())
