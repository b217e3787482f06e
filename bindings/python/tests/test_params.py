"""Parameter sets: loaded from the shipped TOML files, overridden as --set does, and failing
with the CLI's messages as granflow.InputError."""
import pytest

import granflow
from conftest import error_text


def test_load_by_name_and_path_agree(root):
    by_name = granflow.load_params("element_test")
    by_path = granflow.load_params(root / "data" / "params" / "element_test.toml")
    assert by_name.file == by_path.file
    assert by_name.has_frictional and by_name.has_collisional
    assert by_name.to_toml() == by_path.to_toml()


def test_dict_round_trip():
    p = granflow.load_params("element_test")
    d = p.to_dict()
    assert set(d) >= {"frictional", "collisional"}
    q = granflow.load_params(d)
    assert q.file == "<dict>"
    assert q.to_toml() == p.to_toml()


def test_overrides_change_the_value_like_set():
    p = granflow.load_params("element_test", overrides=["frictional.phi_c_deg=25"])
    assert p.to_dict()["frictional"]["phi_c_deg"] == pytest.approx(25)
    q = granflow.load_params("element_test").with_overrides("frictional.phi_c_deg=25")
    assert q.to_toml() == p.to_toml()
    assert granflow.load_params("element_test").to_dict()["frictional"]["phi_c_deg"] != pytest.approx(25)


def test_unknown_set_gives_the_cli_message(cli):
    with pytest.raises(granflow.InputError) as e:
        granflow.load_params("nope")
    assert str(e.value) == error_text(cli("element", "--params", "nope"))
    assert "no parameter set of that name" in str(e.value)
    assert isinstance(e.value, ValueError)


def test_bad_override_gives_the_cli_message(cli):
    with pytest.raises(granflow.InputError) as e:
        granflow.load_params("element_test", overrides=["frictional.phi_c_deg=95"])
    assert str(e.value) == error_text(cli("element", "data/tests/fig6_e099.toml", "--set", "frictional.phi_c_deg=95"))


def test_bad_file_names_file_line_and_key(tmp_path, cli):
    text = (granflow.load_params("element_test").to_toml()
            .replace("phi_c_deg =", "phi_c_degs =", 1))
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    with pytest.raises(granflow.InputError) as e:
        granflow.load_params(bad)
    msg = str(e.value)
    assert msg.startswith(str(bad) + ":") and "phi_c_degs" in msg
    assert msg == error_text(cli("element", "data/tests/fig6_e099.toml", "--params", bad))
    with pytest.raises(granflow.InputError) as e2:
        granflow.parse_params(text, "text.toml")
    assert str(e2.value) == msg.replace(str(bad), "text.toml")


def test_degrees_read_back_as_given():
    p = granflow.load_params("element_test")
    for deg in (30, 33.3, 12.5, 0.1, 89.99, 35.26438968275465):
        q = p.with_overrides(f"frictional.phi_c_deg={deg!r}")
        assert q.to_dict()["frictional"]["phi_c_deg"] == deg
        assert granflow.load_params(q.to_dict()).to_toml() == q.to_toml()
    assert "\nphi_c_deg = 30\n" in granflow.parse_params(p.to_toml().replace("phi_c_deg =", "phi_c_deg = 30 #")).to_toml()


def test_wrong_argument_types():
    # A wrong type raises InputTypeError: an InputError (every bad argument) and a TypeError.
    for call in (lambda: granflow.load_params(42), lambda: granflow.load_params("element_test", overrides=[1]),
                 lambda: granflow.load_params({"frictional": {"K0": object()}}),
                 lambda: granflow.load_params("element_test").with_overrides(3.0),
                 lambda: granflow.parse_params(5), lambda: granflow.element(7),
                 lambda: granflow.calibrate(None)):
        with pytest.raises(granflow.InputTypeError) as e:
            call()
        assert isinstance(e.value, granflow.InputError) and isinstance(e.value, TypeError)
