"""granflow.update: the constitutive update on arrays. Repeated over a constant velocity gradient
it must reproduce the CLI's incremental element test (the same Model::update) point by point."""
import numpy as np
import pytest

import granflow
from conftest import read_csv

DT, STEPS, EVERY = 1e-3, 50, 10
CASES = {  # parameter set, model, e0, sigma_v0 [Pa], T0
    "frictional": ("frictional_element", 0.80, 1e5, None),
    "phase_transition": ("element_test", 0.95, 500.0, 1e-6),
}


def shear_test_file(path, params, e0, sv, T0):
    lines = [f'params = "{params}"', "[test]", 'path = "undrained_simple_shear"', "rate = 1.0",
             f"duration = {STEPS * DT}", f"e0 = {e0}", f"sigma_v0 = {sv}", "k0 = 1.0",
             'solver = "incremental"', f"dt = {DT}", f"outputs = {STEPS // EVERY + 1}"]
    if T0 is not None:
        lines.append(f"T0 = {T0}")
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("model", list(CASES))
def test_repeated_update_reproduces_the_incremental_element_test(model, cli, tmp_path):
    params, e0, sv, T0 = CASES[model]
    f = tmp_path / "shear.toml"
    shear_test_file(f, params, e0, sv, T0)
    proc = cli("element", f, "--out", tmp_path / "ref.csv")
    assert proc.returncode == 0, proc.stderr
    ref = read_csv(tmp_path / "ref.csv")

    n = 3000  # several threads' worth of identical points
    state = {"sigma_f": np.tile(-sv * np.eye(3), (n, 1, 1)), "eps_pd": np.full(n, ref["eps_pd"][0]),
             "e": np.full(n, e0)}
    if T0 is not None:
        state["T"] = np.full(n, T0)
    L = np.zeros((3, 3))
    L[0, 1] = 1.0  # v = (gammadot y, 0, 0)
    p = granflow.load_params(params)
    rows = []
    for k in range(1, STEPS + 1):
        out = granflow.update(p, state, L, DT, model=model, threads=4)
        assert out["ok"].all() and (out["flags"] & granflow.FLAG_ERROR_MASK == 0).all()
        state = {key: out[key] for key in state}
        if k % EVERY == 0:
            rows.append(out)
    assert all(np.array_equal(r["stress"], np.broadcast_to(r["stress"][0], r["stress"].shape)) for r in rows)
    got = {
        "sigma_n_f": [-r["sigma_f"][0, 1, 1] for r in rows],
        "tau_f": [r["sigma_f"][0, 0, 1] for r in rows],
        "sigma_n": [-r["stress"][0, 1, 1] for r in rows],
        "tau": [r["stress"][0, 0, 1] for r in rows],
        "e": [r["e"][0] for r in rows],
        "eps_pd": [r["eps_pd"][0] for r in rows],
    }
    if T0 is not None:
        got["T"] = [r["T"][0] for r in rows]
    assert ref["eps_pd"][-1] > 0  # the path reaches plastic loading
    for name, values in got.items():
        np.testing.assert_allclose(values, ref[name][1:], rtol=1e-8, atol=1e-12 * sv, err_msg=name)


def test_shapes_broadcast_and_thread_independence():
    p = granflow.load_params("element_test")
    rng = np.random.default_rng(1)
    n = 5000
    state = {"sigma_f": np.tile(-500.0 * np.eye(3), (n, 1, 1)), "eps_pd": np.zeros(n),
             "e": rng.uniform(0.7, 0.95, n), "T": rng.uniform(1e-8, 1e-4, n)}
    L = rng.normal(0, 5, (n, 3, 3))
    dt = np.full(n, 1e-4)
    one = granflow.update(p, state, L, dt, threads=1)
    many = granflow.update(p, state, L, 1e-4, threads=8)
    assert set(one) == {"sigma_f", "eps_pd", "e", "T", "stress", "flags", "ok"}
    assert one["stress"].shape == (n, 3, 3) and one["flags"].dtype == np.uint32 and one["ok"].shape == (n,)
    for k in one:
        np.testing.assert_array_equal(one[k], many[k], err_msg=k)
    # point 7 alone, with its own gradient
    single = granflow.update(p, {k: v[7:8] for k, v in state.items()}, L[7], 1e-4)
    np.testing.assert_array_equal(single["stress"][0], one["stress"][7])
    # the input is not modified
    assert (state["sigma_f"] == -500.0 * np.eye(3)).all()


def test_collisional_only_state():
    p = granflow.load_params("element_test")
    L = np.zeros((3, 3))
    L[0, 1] = 50.0
    out = granflow.update(p, {"e": np.array([0.95, 1.05]), "T": np.array([1e-4, 1e-4])}, L, 1e-3, model="collisional")
    assert set(out) == {"e", "T", "stress", "flags", "ok"}
    assert out["ok"].all() and (out["T"] > 1e-4).all()  # shear heats
    assert out["stress"][0, 0, 1] > out["stress"][1, 0, 1] > 0  # denser: more shear stress


def test_failed_point_keeps_its_state_and_gets_nan():
    p = granflow.load_params("element_test")
    state = {"sigma_f": np.tile(-500.0 * np.eye(3), (2, 1, 1)), "eps_pd": np.zeros(2),
             "e": np.array([0.8, 0.8]), "T": np.array([1e-6, -1.0])}
    out = granflow.update(p, state, np.zeros((3, 3)), 1e-4)
    assert out["ok"].tolist() == [True, False]
    assert out["flags"][1] & granflow.FLAGS["inadmissible"]
    assert np.isnan(out["stress"][1]).all() and out["T"][1] == -1.0 and np.isfinite(out["stress"][0]).all()


NAN, INF = float("nan"), float("inf")


@pytest.mark.parametrize("model,key,at,value", [
    ("auto", "sigma_f", (1, 0, 0), NAN), ("auto", "sigma_f", (1, 2, 1), INF), ("auto", "sigma_f", (1, 1, 1), -INF),
    ("auto", "eps_pd", 1, NAN), ("auto", "eps_pd", 1, INF), ("auto", "eps_pd", 1, -0.01),
    ("auto", "e", 1, NAN), ("auto", "T", 1, NAN), ("auto", "T", 1, INF),
    ("frictional", "sigma_f", (1, 0, 1), NAN), ("frictional", "eps_pd", 1, NAN), ("frictional", "e", 1, INF),
    ("collisional", "e", 1, NAN), ("collisional", "e", 1, INF), ("collisional", "T", 1, INF),
])
def test_non_finite_or_inadmissible_state_fails_that_point(model, key, at, value):
    keys = {"auto": ["sigma_f", "eps_pd", "e", "T"], "frictional": ["sigma_f", "eps_pd", "e"],
            "collisional": ["e", "T"]}[model]
    full = {"sigma_f": np.tile(-500.0 * np.eye(3), (2, 1, 1)), "eps_pd": np.zeros(2), "e": np.full(2, 0.95),
            "T": np.full(2, 1e-6)}
    state = {k: full[k] for k in keys}
    state[key][at] = value
    L = np.zeros((3, 3))
    L[0, 1] = 10.0
    out = granflow.update("element_test", state, L, 1e-4, model=model)
    assert out["ok"].tolist() == [True, False]
    assert out["flags"][1] & granflow.FLAGS["inadmissible"]
    assert np.isnan(out["stress"][1]).all() and np.isfinite(out["stress"][0]).all()
    for k in keys:  # the failed point keeps its state, the bad value included
        np.testing.assert_array_equal(out[k][1], state[k][1], err_msg=k)


@pytest.mark.parametrize("state,grad_v,dt,message", [
    ({"e": np.ones(2)}, np.zeros((3, 3)), 1e-3, "state is missing 'sigma_f'"),
    ({"sigma_f": np.zeros((2, 3, 3)), "eps_pd": np.zeros(2), "e": np.ones(2), "T": np.ones(3)}, np.zeros((3, 3)),
     1e-3, "state['T'] has shape (3,), expected (2,)"),
    ({"sigma_f": np.zeros((2, 3, 3)), "eps_pd": np.zeros(2), "e": np.ones(2), "T": np.ones(2)}, np.zeros((2, 3)),
     1e-3, "grad_v has shape (2, 3), expected (3, 3) or (2, 3, 3)"),
    ({"sigma_f": np.zeros((2, 3, 3)), "eps_pd": np.zeros(2), "e": np.ones(2), "T": np.ones(2)}, np.zeros((3, 3)),
     0.0, "dt must be finite and > 0"),
    ({"sigma_f": np.zeros((2, 3, 3)), "eps_pd": np.zeros(2), "e": np.ones(2), "T": np.ones(2), "s": np.ones(2)},
     np.zeros((3, 3)), 1e-3, "state key 's' is not part of the auto state"),
    ({"sigma_f": np.zeros((2, 3, 3)), "eps_pd": np.zeros(2), "e": np.ones(2), "T": np.ones(2)},
     np.array([[0, NAN, 0], [0, 0, 0], [0, 0, 0]]), 1e-3, "grad_v[0, 1] = nan is not finite"),
    ({"sigma_f": np.zeros((2, 3, 3)), "eps_pd": np.zeros(2), "e": np.ones(2), "T": np.ones(2)},
     np.where(np.arange(18).reshape(2, 3, 3) == 15, INF, 0.0), 1e-3, "grad_v[1, 2, 0] = inf is not finite"),
    ({"sigma_f": np.zeros((2, 3, 3)), "eps_pd": np.zeros(2), "e": np.ones(2), "T": np.ones(2)}, np.zeros((3, 3)),
     np.array([1e-3, NAN]), "dt must be finite and > 0"),
])
def test_bad_arrays_are_input_errors(state, grad_v, dt, message):
    with pytest.raises(granflow.InputError) as e:
        granflow.update("element_test", state, grad_v, dt)
    assert message in str(e.value)


def test_wrong_types_are_input_errors_and_type_errors():
    for call in (lambda: granflow.update("element_test", {"e": "dense"}, np.zeros((3, 3)), 1e-3, model="collisional"),
                 lambda: granflow.update("element_test", {"e": np.ones(1), "T": np.ones(1)}, np.zeros((3, 3)), 1e-3,
                                         model="collisional", threads="all")):
        with pytest.raises(granflow.InputError) as e:
            call()
        assert isinstance(e.value, TypeError) and isinstance(e.value, granflow.InputTypeError)


def test_model_needs_its_table():
    with pytest.raises(granflow.InputError, match=r"needs a \[collisional\] table"):
        granflow.update("frictional_element", {"e": np.ones(1), "T": np.ones(1)}, np.zeros((3, 3)), 1e-3,
                        model="collisional")
    with pytest.raises(granflow.InputError, match="model 'viscous'"):
        granflow.update("element_test", {"e": np.ones(1)}, np.zeros((3, 3)), 1e-3, model="viscous")


def test_a_view_too_large_to_copy_is_a_memory_error():
    # a float32 view of 2^50 points (no memory of its own) needs an 8 PiB float64 copy
    huge = np.broadcast_to(np.float32(0.9), (2**50,))
    with pytest.raises(MemoryError, match=r"state\['e'\] has 1125899906842624 elements; its float64 copy needs "
                                          r"8\.39e\+06 GiB"):
        granflow.update("element_test", {"e": huge, "T": huge}, np.zeros((3, 3)), 1e-3, model="collisional")
