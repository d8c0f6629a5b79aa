"""The paper's experiments as commands: quick settings, JSON contract, files written."""
import json
import subprocess
import sys

import numpy as np

from nlos_cl.apps import reproduce as rp


def test_fwhm_of_a_gaussian():
    t = np.arange(2000) * 1e-12
    sigma = 100e-12
    y = np.exp(-0.5 * ((t - 1e-9) / sigma) ** 2)
    assert rp.fwhm_ns(t, y) == pytest_approx(2.3548 * 0.1, 1e-3)


def pytest_approx(value, rel):
    import pytest
    return pytest.approx(value, rel=rel)


def test_fig10_quick_json_contract(tmp_path):
    out = subprocess.run([sys.executable, "-m", "nlos_cl.cli", "reproduce", "fig10", "--quick",
                          "--json", "--out", str(tmp_path)], capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    summary = json.loads(out.stdout)
    for method in ("filter", "fit", "raw"):
        assert set(summary[method]) >= {"mean_m", "std_m", "max_m"}
    assert summary["filter"]["mean_m"] < 0.12  # the paper's tolerance, even on the coarse grid
    assert (tmp_path / "fig10.csv").read_text().count("\n") == 26  # header + 25 positions
    assert (tmp_path / "fig10.png").stat().st_size > 10_000


def test_table1_reproduces_the_paper_within_10cm(tmp_path):
    (result,) = rp.run("table1", rp.Settings.make(quick=True), tmp_path)
    assert all(row["distance_to_paper_m"] < 0.1 for row in result.rows)
