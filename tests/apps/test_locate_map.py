"""`nlos-cl locate --map` writes by extension (issue 56 item 3): .npz arrays along the file's
axes with the frame, units and estimator inside, a .png figure, anything else refused."""
import json
import subprocess
import sys

import numpy as np
import pytest


def run(*args):
    return subprocess.run([sys.executable, "-m", "nlos_cl.apps.cli", *args], check=False,
                          capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    path = tmp_path_factory.mktemp("map") / "c.h5"
    out = run("simulate", "--out", str(path), "--facet", "0.02", "--snr-db", "10")
    assert out.returncode == 0, out.stderr
    return path


def test_npz_map_names_its_frame_axes_and_estimator(capture, tmp_path):
    path = tmp_path / "m.npz"
    out = run("locate", str(capture), "--json", "--estimator", "paper", "--map", str(path))
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout)
    with np.load(path, allow_pickle=False) as m:
        assert json.loads(str(m["frame"]))["name"] == r["frame"]["name"] == "ytal"
        assert list(m["axes"]) == ["X", "Y", "Z"] and str(m["estimator"]) == "paper"
        assert str(m["units"]).startswith("m") and "likelihood" in str(m["score_kind"])
        score, axes = m["score"], [m[a] for a in m["axes"]]
        assert score.shape == tuple(a.size for a in axes) and score.size == r["region"]["cells"]
        assert all(a.size == 1 or np.all(np.diff(a) > 0) for a in axes)
        # the map's best cell is the answer's argmax cell, in the file's coordinates
        best = np.unravel_index(np.argmax(score), score.shape)
        cell = [a[i] for a, i in zip(axes, best)]
        assert np.allclose(cell, r["argmax_cell"], atol=1e-4), (cell, r["argmax_cell"])


def test_png_map_is_a_figure(capture, tmp_path):
    path = tmp_path / "m.png"
    out = run("locate", str(capture), "--estimator", "paper", "--map", str(path))
    assert out.returncode == 0, out.stderr
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000


def test_other_extensions_are_refused_before_any_work(capture, tmp_path):
    path = tmp_path / "m.txt"
    out = run("locate", str(capture), "--map", str(path))
    assert out.returncode == 2 and "--map" in out.stderr and ".npz" in out.stderr
    assert ".png" in out.stderr and len(out.stderr.strip().splitlines()) == 1
    assert not path.exists()
