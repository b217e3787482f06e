"""`import granflow` from an install prefix (cmake --install), in a fresh interpreter started in an
empty folder, with PYTHONPATH naming only the prefix: the module and the shipped data it finds
(<prefix>/share/granflow/data, not the source tree's)."""
import os
import shutil
import subprocess
import sys

import pytest


def test_import_from_install_prefix(tmp_path):
    build = os.environ.get("GRANFLOW_BUILD_DIR")
    cmake = shutil.which("cmake")
    if not build or not cmake:
        pytest.skip("needs GRANFLOW_BUILD_DIR (set by ctest) and cmake")
    prefix = tmp_path / "prefix"
    proc = subprocess.run([cmake, "--install", build, "--prefix", prefix],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    site = prefix / os.environ.get("GRANFLOW_PYTHON_INSTALL_DIR", "lib/python3/dist-packages")
    assert (site / "granflow" / "__init__.py").exists()
    empty = tmp_path / "empty"
    empty.mkdir()
    code = ("import granflow, sys; print(granflow.__file__); print(granflow.data_directory()); "
            "r = granflow.element({'test': {'path': 'oedometric', 'rate': 0.1, 'duration': 1.0, 'outputs': 3}}, "
            "params='frictional_element'); print(len(r['time']))")
    env = {"PATH": os.environ.get("PATH", ""), "PYTHONPATH": str(site)}
    run = subprocess.run([sys.executable, "-c", code], cwd=empty, env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    file, data, rows = run.stdout.split()
    assert file.startswith(str(site)) and rows == "3"
    assert data == str(prefix / "share" / "granflow" / "data")
