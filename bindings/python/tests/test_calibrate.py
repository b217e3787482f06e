"""Calibration jobs: the fitted parameters and report as the CLI writes them."""
import os

import numpy as np
import pytest

import granflow
from conftest import error_text, read_csv

JOB = "data/calibration/dem_collisional_mu0.toml"


@pytest.fixture(scope="module")
def cli_fit(cli, tmp_path_factory):
    out = tmp_path_factory.mktemp("cal") / "fit"
    proc = cli("calibrate", JOB, "--out", out, "--quiet", "--no-plot")
    assert proc.returncode == 0, proc.stderr
    return out


def test_fit_matches_the_cli(cli_fit):
    r = granflow.calibrate(JOB, threads=2)
    ref = read_csv(cli_fit / "report_parameters.csv")
    assert list(r["parameters"]) == list(ref["key"]) == ["collisional.V_sd", "collisional.V_m"]
    np.testing.assert_allclose(list(r["parameters"].values()), ref["fitted"], rtol=1e-11)
    np.testing.assert_allclose(list(r["start"].values()), ref["start"], rtol=1e-12)
    np.testing.assert_allclose(list(r["rel_sd"].values()), ref["rel_sd"], rtol=1e-9)
    fitted_file = granflow.load_params(cli_fit / "dem_mu0.toml")
    assert r["fitted"].to_dict()["collisional"] == fitted_file.to_dict()["collisional"]
    assert r["misfit"] < r["misfit_start"]
    curves = read_csv(cli_fit / "report_curves.csv")
    assert [c["label"] for c in r["curves"]] == [f"{e}:{d}" for e, d in zip(curves["experiment"], curves["data_column"])]
    np.testing.assert_allclose([c["rmse"] for c in r["curves"]], curves["rmse"], rtol=1e-8)
    c0 = r["curves"][0]
    assert c0["x"].shape == c0["y"].shape == c0["model"].shape == (8,)
    assert r["correlation"].shape == (2, 2) and r["sensitivity"].shape == (15, 2)
    assert "misfit: start 1.7076748 -> final" in r["report"] and r["ensemble"] is None and r["out"] is None


def test_out_writes_the_cli_folder(cli_fit, tmp_path):
    out = tmp_path / "fit"
    r = granflow.calibrate(JOB, out=out)
    assert r["out"] == str(out)
    assert sorted(os.listdir(out)) == sorted(os.listdir(cli_fit))
    assert (out / "dem_mu0.toml").read_text() == (cli_fit / "dem_mu0.toml").read_text()
    with pytest.raises(granflow.InputError, match="exists"):
        granflow.calibrate(JOB, out=out)
    granflow.calibrate(JOB, out=out, force=True)


def test_evaluate_only_keeps_the_start(cli_fit):
    r = granflow.calibrate(JOB, evaluate=True)
    assert r["parameters"] == r["start"] and r["misfit"] == pytest.approx(r["misfit_start"])


def test_ensemble_job_returns_the_posterior(tmp_path, root):
    job = (root / JOB).read_text().replace("[algorithm]", '[algorithm]\nmethod = "ensemble"')
    job = job.replace('data = "../', f'data = "{root}/data/')
    job = job.replace("global_evaluations = 400\nlocal_evaluations = 300\n", "")
    job = job.replace('global = "GN_CRS2_LM"\nlocal = "LN_BOBYQA"\n', "")
    job += "\n[ensemble]\nmembers = 16\niterations = 2\npolish = false\n"
    f = tmp_path / "ens.toml"
    f.write_text(job)
    r = granflow.calibrate(f, threads=2)
    e = r["ensemble"]
    assert e["posterior"].shape == (16, 2)
    assert set(e["summary"]) == {"collisional.V_sd", "collisional.V_m"}
    s = e["summary"]["collisional.V_sd"]
    assert 0.58 <= s["q05"] <= s["median"] <= s["q95"] <= 0.75


def test_bad_job_gives_the_cli_message(cli, tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text(open(JOB).read().replace("lower = 0.58", "lower = 0.9"))
    with pytest.raises(granflow.InputError) as e:
        granflow.calibrate(f)
    assert str(e.value) == error_text(cli("calibrate", f, "--out", tmp_path / "o"))
    assert str(e.value).startswith(f"{f}:12:") and "free[0].upper" in str(e.value)
