"""MPM runs on the CPU twin (and CUDA where present): series, tracked points, final surface and
particles as arrays, equal to what the CLI writes for the same scene and overrides."""
import numpy as np
import pytest

import granflow
from conftest import error_text, read_csv

SCENE = "mpm/scenes/column_collapse_ci.toml"
# A coarse grid and 0.02 s of collapse after the consolidation: 128 points, 1200 steps.
SETS = ["grid.h=0.025", "time.dt=1e-4"]
STOP = 0.12


@pytest.fixture(scope="module")
def cli_run(cli, tmp_path_factory):
    out = tmp_path_factory.mktemp("mpm") / "cc"
    args = ["mpm", SCENE, "--out", out, "--no-png", "--quiet", "--stop-after", STOP]
    for s in SETS:
        args += ["--set", s]
    proc = cli(*args)
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.fixture(scope="module")
def run():
    return granflow.mpm(SCENE, overrides=SETS, stop_after=STOP)


def test_series_and_tracks_match_the_cli_csvs(cli_run, run):
    for name, key in (("runout.csv", "series"), ("tracked.csv", "tracked"), ("profile_final.csv", "surface")):
        ref = read_csv(cli_run / name)
        got = run[key]
        assert list(got) == list(ref), name  # the CSV's columns, in order
        for col, values in ref.items():
            if values.dtype.kind == "U":
                assert got[col].tolist() == values.tolist(), (name, col)
            else:  # the CSVs hold 8 significant digits (half a unit: <= 5e-8)
                np.testing.assert_allclose(got[col], values, rtol=1e-7, atol=1e-20, err_msg=f"{name}:{col}")
    assert run["series"]["t"][-1] == pytest.approx(STOP)
    assert run["t_end"] == pytest.approx(STOP) and run["steps"] == 1200


def test_gauges_materials_and_forces_match_the_cli(cli, tmp_path):
    # the CI column into a low wall (forces) with a gauge before it, as two layers of materials
    text = open("mpm/scenes/column_obstacle_ci.toml").read()
    assert text.count("[[body]]") == 1 and "max = [0.20, 0.10]" in text
    text = text.replace("[material]", '[[material]]\nname = "a"', 1)
    text = text.replace("[[body]]", '[[body]]\nmaterial = "a"').replace("max = [0.20, 0.10]", "max = [0.20, 0.05]")
    text += ('\n[[material]]\nname = "b"\nparameters = "column_collapse"\nmodel = "phase_transition"\ne0 = 0.9\n'
             '\n[[body]]\nmaterial = "b"\nmin = [0.0, 0.05]\nmax = [0.20, 0.10]\n'
             '\n[[gauge]]\nname = "g"\nfrom = [0.22, 0.0]\nto = [0.22, 0.12]\n')
    scene = tmp_path / "scene.toml"
    scene.write_text(text)
    sets = ["stage[1].duration=0.3", "output.times=[0.3]"]
    out = tmp_path / "o"
    proc = cli("mpm", scene, "--out", out, "--no-png", "--quiet", *[w for s in sets for w in ("--set", s)])
    assert proc.returncode == 0, proc.stderr
    got = granflow.mpm(str(scene), overrides=sets)
    for name, key in (("gauges.csv", "gauges"), ("materials.csv", "materials")):
        ref = read_csv(out / name)
        assert list(got[key]) == list(ref), name
        for col, values in ref.items():
            if values.dtype.kind == "U":
                assert got[key][col].tolist() == values.tolist(), (name, col)
            else:
                np.testing.assert_allclose(got[key][col], values, rtol=1e-7, atol=1e-20, err_msg=f"{name}:{col}")
    assert set(got["materials"]["material"]) == {"a", "b"}
    assert got["gauges"]["points"].max() > 0  # the flow reaches the gauge
    wall = got["forces"]["low wall"]
    assert 0 < wall["peak"] <= wall["step_peak"] and wall["impulse"] > 0
    assert "force on low wall: peak" in proc.stdout
    assert "forces: a node two boundaries hold counts for the first of the obstacles, the walls" in proc.stdout
    last = {m: got["materials"]["runout"][got["materials"]["material"] == m][-1] for m in ("a", "b")}
    for m, runout in last.items():  # the CLI's closing lines per material
        assert f"material {m}: final run-out {runout:.4f} m" in proc.stdout


def test_final_particles(run):
    p = run["particles"]
    n = run["particles_count"]
    assert n == 128 and p["x"].shape == p["v"].shape == (n, 2)
    for k in ("p", "q", "eps_pd", "T", "eta_c", "K_col", "e", "sxx", "syy", "sxy", "m"):
        assert p[k].shape == (n,), k
        assert np.isfinite(p[k]).all(), k
    # the highest particle lies at the free surface the run reports
    assert p["x"][:, 1].max() <= run["surface"]["surface_y"].max() + 1e-12
    assert run["final"]["runout"] == pytest.approx(run["series"]["runout"][-1])
    assert (p["x"][:, 0] >= 0).all() and (p["m"] > 0).all()


def test_parameter_override_changes_the_run(run):
    other = granflow.mpm(SCENE, overrides=SETS + ["frictional.phi_c_deg=20"], stop_after=STOP)
    assert not np.array_equal(other["particles"]["x"], run["particles"]["x"])


def test_bad_override_gives_the_cli_message(cli):
    with pytest.raises(granflow.InputError) as e:
        granflow.mpm(SCENE, overrides=["grid.h=0.02"])
    assert str(e.value) == error_text(cli("mpm", SCENE, "--set", "grid.h=0.02", "--no-png"))
    assert "whole number of cells" in str(e.value)


def test_bad_stop_after_is_an_input_error():
    for bad in (float("nan"), float("inf")):  # both ran the whole scene
        with pytest.raises(granflow.InputError, match="stop_after = (nan|inf): must be a finite time"):
            granflow.mpm(SCENE, overrides=SETS, stop_after=bad)
    with pytest.raises(granflow.InputTypeError):
        granflow.mpm(SCENE, overrides=SETS, stop_after="soon")


def test_cuda_backend():
    if granflow.cuda_available():
        r = granflow.mpm(SCENE, overrides=SETS, stop_after=STOP, backend="cuda")
        assert r["particles"]["x"].shape == (128, 2) and "CPU" not in r["device"]
    else:
        with pytest.raises(RuntimeError, match="without CUDA|no CUDA|device"):
            granflow.mpm(SCENE, overrides=SETS, stop_after=STOP, backend="cuda")
    with pytest.raises(granflow.InputError, match="backend 'gpu'"):
        granflow.mpm(SCENE, backend="gpu")


def test_ctrl_c_stops_a_run_and_restores_pythons_handler():
    import os
    import signal
    import threading
    import time
    timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    t0 = time.time()
    with pytest.raises(KeyboardInterrupt):
        granflow.mpm(SCENE)  # about a minute to the end
    assert time.time() - t0 < 10
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_params_names_a_material_as_the_cli_does(cli, tmp_path):
    # two layers of materials: params="NAME=SET" (or a list of them) changes that material's set
    text = open(SCENE).read().replace("[material]", '[[material]]\nname = "strong"', 1)
    text = text.replace("[[body]]", '[[body]]\nmaterial = "strong"', 1).replace("max = [0.20, 0.10]", "max = [0.20, 0.05]")
    text += ('\n[[material]]\nname = "spare"\nparameters = "column_collapse"\nmodel = "phase_transition"\ne0 = 0.9\n'
             '\n[[body]]\nmaterial = "spare"\nmin = [0.0, 0.05]\nmax = [0.20, 0.10]\n')
    scene = tmp_path / "scene.toml"
    scene.write_text(text)
    base = granflow.mpm(str(scene), overrides=SETS, stop_after=STOP)
    one = granflow.mpm(str(scene), params="strong=flume", overrides=SETS, stop_after=STOP)
    both = granflow.mpm(str(scene), params=["strong=flume", "spare=flume"], overrides=SETS, stop_after=STOP)
    assert not np.array_equal(one["particles"]["x"], base["particles"]["x"])  # flume's set differs
    assert not np.array_equal(both["particles"]["x"], one["particles"]["x"])
    out = tmp_path / "o"
    proc = cli("mpm", scene, "--out", out, "--no-png", "--quiet", "--params", "strong=flume", "--stop-after", STOP,
               *[w for s in SETS for w in ("--set", s)])
    assert proc.returncode == 0, proc.stderr
    ref = read_csv(out / "runout.csv")
    np.testing.assert_allclose(one["series"]["runout"], ref["runout"], rtol=1e-7, atol=1e-20)
    with pytest.raises(granflow.InputError) as e:  # a set for no material: the CLI's message
        granflow.mpm(str(scene), params="strong", overrides=SETS, stop_after=STOP)
    assert str(e.value) == error_text(cli("mpm", scene, "--params", "strong", "--no-png",
                                          *[w for s in SETS for w in ("--set", s)]))
