"""Element tests: from a test file or a dict, the CLI's columns and values."""
import numpy as np
import pytest

import granflow
from conftest import error_text, read_csv

FIG6 = "data/tests/fig6_e099.toml"
FIG4 = "data/tests/fig4_e080.toml"


@pytest.fixture(scope="module")
def fig6_cli(cli, tmp_path_factory):
    out = tmp_path_factory.mktemp("el") / "fig6.csv"
    proc = cli("element", FIG6, "--out", out)
    assert proc.returncode == 0, proc.stderr
    with open(out) as f:
        header = f.readline().strip().split(",")
    return header, read_csv(out)


def test_file_matches_cli_csv(fig6_cli):
    header, ref = fig6_cli
    r = granflow.element(FIG6)
    assert list(r) == header == granflow.element_columns()
    for name in header:
        assert r[name].shape == (391,)
        # the CSV holds 10 significant digits
        np.testing.assert_allclose(r[name], ref[name], rtol=1e-9, atol=1e-300, err_msg=name)


def test_dict_equals_file(root):
    test = {"params": "element_test",
            "test": {"path": "undrained_simple_shear", "programme": "acceleration", "rate": 10.0, "hold": 0.5,
                     "acceleration": 50.0, "duration": 20.0, "e0": 0.99, "sigma_v0": 500.0, "T0": 1e-15,
                     "solver": "cvode", "rtol": 1e-6, "atol": 1e-9, "outputs": np.int64(391)}}
    a = granflow.element(test)
    b = granflow.element(root / FIG6)
    for name in b:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_params_and_overrides_like_the_cli(cli, tmp_path):
    out = tmp_path / "o.csv"
    proc = cli("element", FIG4, "--params", "frictional_element", "--set", "frictional.phi_c_deg=25", "--out", out)
    assert proc.returncode == 0, proc.stderr
    ref = read_csv(out)
    r, stats = granflow.element(FIG4, params=granflow.load_params("frictional_element"),
                                overrides=["frictional.phi_c_deg=25"], stats=True)
    np.testing.assert_allclose(r["q"], ref["q"], rtol=1e-9)
    assert not np.allclose(r["q"], granflow.element(FIG4)["q"], rtol=1e-3)
    assert stats["steps"] > 0 and stats["rhs_evals"] >= stats["steps"]


def test_unknown_key_in_dict_names_it():
    with pytest.raises(granflow.InputError) as e:
        granflow.element({"test": {"path": "undrained_simple_shear", "rat": 1.0}})
    assert str(e.value).startswith("<dict>") and "rat" in str(e.value)


def test_bad_value_gives_the_cli_message(cli, tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text('params = "element_test"\n[test]\npath = "oedometric"\nrate = -1.0\n')
    with pytest.raises(granflow.InputError) as e:
        granflow.element(f)
    assert str(e.value) == error_text(cli("element", f))
    assert str(e.value).startswith(f"{f}:4")


def test_missing_file_is_an_input_error(cli):
    with pytest.raises(granflow.InputError) as e:
        granflow.element("no/such/test.toml")
    assert str(e.value) == error_text(cli("element", "no/such/test.toml"))
