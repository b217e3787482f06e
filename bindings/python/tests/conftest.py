"""Shared by the granflow pytest suite: the CLI (the reference every result is compared with),
CSV reading, the source root. ctest sets PYTHONPATH to the build tree and GRANFLOW_CLI."""
import csv
import os
import pathlib
import subprocess

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]


@pytest.fixture(scope="session")
def root():
    return ROOT


@pytest.fixture(scope="session")
def cli():
    """Runs the granflow program; returns the CompletedProcess (check=False)."""
    exe = os.environ.get("GRANFLOW_CLI", str(ROOT / "build" / "granflow"))
    if not os.path.exists(exe):
        pytest.skip(f"granflow program not found at {exe} (set GRANFLOW_CLI)")

    def run(*args, cwd=ROOT):
        return subprocess.run([exe, *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=300)
    return run


def read_csv(path):
    """CSV with a header -> dict column -> array (strings kept where a column is not numeric)."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    cols = {}
    for j, name in enumerate(rows[0]):
        vals = [r[j] for r in rows[1:]]
        try:
            cols[name] = np.array([float(v) if v != "" else np.nan for v in vals])
        except ValueError:
            cols[name] = np.array(vals)
    return cols


def error_text(proc):
    """The message of a failed CLI run without its 'granflow: error: ' prefix."""
    assert proc.returncode != 0, proc.stdout
    line = proc.stderr.strip().splitlines()[-1]
    return line.split("error: ", 1)[1] if "error: " in line else line
