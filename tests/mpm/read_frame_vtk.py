#!/usr/bin/env python3
"""VTK's own reader on granflow's raw appended frames (issue 49).

    read_frame_vtk.py GRANFLOW SCENE WORK_DIR

Runs `granflow mpm SCENE` twice for a short time, with the default output.format (raw appended
binary) and with output.format = "base64", then loads every frame of the first run with
vtkXMLUnstructuredGridReader and checks each of its arrays, bit for bit, against the same frame
of the second run decoded here without VTK (base64 and struct); the points lie within the grid.
Exits 77 (skipped) where python3-vtk9 or numpy is missing.
"""
import base64
import os
import shutil
import struct
import subprocess
import sys
import xml.etree.ElementTree as ET

try:
    import tomllib  # Python 3.11
    import numpy as np
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy
except ImportError as e:
    print("read_frame_vtk.py: skipped, %s (the test needs python3-vtk9, python3-numpy and Python 3.11)" % e)
    sys.exit(77)


CELLS = ("connectivity", "offsets")


def run(granflow, scene, out, extra):
    shutil.rmtree(out, ignore_errors=True)
    cmd = [granflow, "mpm", scene, "--out", out, "--no-png", "--quiet", "--stop-after", "0.06"] + extra
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)


def frames(out):
    return [d.get("file") for d in ET.parse(os.path.join(out, "frames.pvd")).getroot().iter("DataSet")]


def read_base64(path):
    """name -> values (components interleaved) of an inline base64 frame, UInt32 byte counts."""
    root = ET.parse(path).getroot()
    assert root.get("header_type") == "UInt32" and root.get("byte_order") == "LittleEndian", path
    types = {"Float64": "<f8", "Int32": "<i4", "UInt8": "u1"}
    arrays = {}
    for da in root.iter("DataArray"):
        assert da.get("format") == "binary", (path, da.get("Name"))
        raw = base64.b64decode(da.text.strip())
        (nbytes,) = struct.unpack("<I", raw[:4])
        assert nbytes + 4 == len(raw), (path, da.get("Name"))
        arrays[da.get("Name")] = np.frombuffer(raw[4:], dtype=types[da.get("type")])
    return arrays


def read_vtk(path):
    """name -> values of a frame as VTK reads it: points, cells and point data."""
    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(path)
    r.Update()
    if r.GetErrorCode() != 0:
        raise SystemExit("%s: VTK error %d" % (path, r.GetErrorCode()))
    grid = r.GetOutput()
    arrays = {"position": vtk_to_numpy(grid.GetPoints().GetData()).ravel()}
    # VTK 9 keeps n + 1 offsets from 0; the file has the n ends
    arrays["connectivity"] = vtk_to_numpy(grid.GetCells().GetConnectivityArray())
    arrays["offsets"] = vtk_to_numpy(grid.GetCells().GetOffsetsArray())[1:]
    arrays["types"] = vtk_to_numpy(grid.GetCellTypesArray())
    pd = grid.GetPointData()
    for k in range(pd.GetNumberOfArrays()):
        arrays[pd.GetArrayName(k)] = vtk_to_numpy(pd.GetArray(k)).ravel()
    return grid.GetNumberOfPoints(), arrays


def main():
    granflow, scene, work = sys.argv[1:4]
    raw_out, b64_out = os.path.join(work, "raw"), os.path.join(work, "base64")
    run(granflow, scene, raw_out, [])
    run(granflow, scene, b64_out, ["--set", 'output.format="base64"'])
    with open(scene, "rb") as f:
        grid = tomllib.load(f)["grid"]
    lo = np.array(grid["origin"] + [0.0] * (3 - len(grid["origin"])))
    hi = lo + np.array(grid["size"] + [0.0] * (3 - len(grid["size"])))
    names = frames(raw_out)
    if len(names) < 2 or names != frames(b64_out):
        raise SystemExit("frames.pvd: %s against %s" % (names, frames(b64_out)))
    for name in names:
        with open(os.path.join(raw_out, name), "rb") as f:
            head = f.read(400)
        if b'header_type="UInt64"' not in head or b'format="appended"' not in head:
            raise SystemExit("%s: not a raw appended frame: %r" % (name, head))
        n, got = read_vtk(os.path.join(raw_out, name))
        want = read_base64(os.path.join(b64_out, name))
        if sorted(got) != sorted(want):
            raise SystemExit("%s: arrays %s, the base64 frame has %s" % (name, sorted(got), sorted(want)))
        for key, w in want.items():
            g = got[key]
            if key in CELLS:  # VTK holds them as its id type
                same = g.shape == w.shape and np.array_equal(g, w)
            else:
                same = g.dtype == w.dtype and g.shape == w.shape and g.tobytes() == w.tobytes()
            if not same:
                raise SystemExit("%s: %s differs (%s %s against %s %s)" % (name, key, g.dtype, g.shape, w.dtype, w.shape))
        x = got["position"].reshape(-1, 3)
        if n == 0 or len(x) != n or (x < lo).any() or (x > hi).any():
            raise SystemExit("%s: %d points, some outside the grid %s to %s" % (name, n, lo, hi))
        print("%s: %d points, %d arrays equal bit for bit" % (name, n, len(want)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
