"""The Fig. 6 example of docs/python.md runs as printed, draws its PNG, and its curves are those
of `granflow figures` (fig6.csv, fig6_sweep.csv), run now by the CLI."""
import re

import numpy as np
import pytest

import granflow
from conftest import read_csv


def example(root):
    text = (root / "docs" / "python.md").read_text()
    section = text.split("## Example: Fig. 6", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_fig6_example(root, tmp_path, monkeypatch, cli):
    pytest.importorskip("matplotlib")
    runs = []
    real = granflow.element

    def recording(test, *a, **k):
        r = real(test, *a, **k)
        runs.append((test["test"]["programme"], test["test"]["e0"], r))
        return r
    monkeypatch.setattr(granflow, "element", recording)
    monkeypatch.chdir(tmp_path)
    exec(compile(example(root), "docs/python.md", "exec"), {})
    assert (tmp_path / "fig6_python.png").stat().st_size > 10000
    assert len(runs) == 6
    figures = tmp_path / "figures"
    proc = cli("figures", "--out", figures)
    assert proc.returncode == 0, proc.stderr
    refs = {"acceleration": read_csv(figures / "fig6.csv"), "sweep": read_csv(figures / "fig6_sweep.csv")}
    for programme, e0, r in runs:
        ref = refs[programme]
        rows = ref["e0"] == e0
        assert rows.sum() == len(r["shear_rate"]) > 20
        for col in ("shear_rate", "sigma_n", "tau"):
            # the CSVs hold 9 significant digits
            np.testing.assert_allclose(r[col], ref[col][rows], rtol=1e-8, atol=1e-20, err_msg=f"{programme} {e0} {col}")
