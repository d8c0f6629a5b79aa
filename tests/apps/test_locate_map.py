"""`nlos-cl locate --map` writes by extension: .npz arrays along the file's axes with the
frame, units and estimator inside, a .png figure, anything else refused; where the search
zoomed in on one answer, both hold the whole search region's map as well (every target)."""
import json
import shutil
import subprocess
import sys

import numpy as np
import pytest


def run(*args):
    return subprocess.run([sys.executable, "-m", "nlos_cl.apps.cli", *args], check=False,
                          capture_output=True, text=True, timeout=600)


def _simulated(tmp_path_factory, folder, *options):
    """A capture `nlos-cl simulate *options` wrote into a fresh folder."""
    path = tmp_path_factory.mktemp(folder) / "c.h5"
    out = run("simulate", *options, "--out", str(path))
    assert out.returncode == 0, out.stderr
    return path


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    return _simulated(tmp_path_factory, "map", "--facet", "0.02", "--snr-db", "10")


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


@pytest.fixture(scope="module")
def two(tmp_path_factory):
    """Two squares 2.1 m apart (docs/scenes/two_squares.yaml): the default region is searched
    coarse, then zoomed around one of them."""
    return _simulated(tmp_path_factory, "two", "docs/scenes/two_squares.yaml")


def test_npz_map_of_a_zoomed_search_holds_the_whole_region(two, tmp_path):
    from nlos_cl.apps.locate_map import REGION_MAP_CELLS
    path = tmp_path / "m.npz"
    out = run("locate", str(two), "--json", "--targets", "2", "--map", str(path))
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout)
    truths = np.array(r["truths"])
    with np.load(path, allow_pickle=False) as m:
        axes = list(m["axes"])
        fine = [m[a] for a in axes]
        whole = [m[f"region_{a}"] for a in axes]
        assert m["region_score"].shape == tuple(a.size for a in whole)
        assert m["region_score"].size <= REGION_MAP_CELLS and "histograms" in str(m["region_note"])
    # the final grid is one target's neighbourhood; the region's map spans both targets
    outside = [not all(a[0] <= v <= a[-1] for a, v in zip(fine, t)) for t in truths]
    assert any(outside), "the scene no longer zooms: this test needs a zoomed search"
    for t in np.vstack([truths, [x["position"] for x in r["targets"]]]):
        assert all(a[0] - 0.05 <= v <= a[-1] + 0.05 for a, v in zip(whole, t)), (t, whole)
    assert all(w[0] <= f[0] and f[-1] <= w[-1] + 1e-9 for f, w in zip(fine, whole))


def test_png_map_of_a_zoomed_search_draws_the_region_and_the_final_grid(two, tmp_path,
                                                                      monkeypatch):
    from nlos_cl.apps import plotting
    from nlos_cl.apps.cli import main as cli
    drawn, draw = [], plotting.map_figure
    monkeypatch.setattr(plotting, "map_figure", lambda fh, view: (drawn.append(view),
                                                                   draw(fh, view)))
    path = tmp_path / "m.png"
    assert cli(["locate", str(two), "--targets", "2", "--map", str(path)]) == 0
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    [view] = drawn
    whole, fine = view["panels"]
    assert whole["inset"] is not None and "whole search region" in whole["title"]
    assert whole["image"].shape == (whole["depth"].size, whole["lateral"].size)
    # every truth and estimate (lateral X, depth Z of y-tal's) lies on the region's panel
    assert len(view["truths"]) == 2 and len(view["targets"]) == 2
    for x, z in np.vstack([view["truths"], [c for c, _ in view["targets"]]]):
        assert whole["lateral"][0] - 0.05 <= x <= whole["lateral"][-1] + 0.05
        assert whole["depth"][0] - 0.05 <= z <= whole["depth"][-1] + 0.05
    assert all(cov is not None and np.all(np.isfinite(cov)) for _, cov in view["targets"])
    assert fine["lateral"].size * fine["depth"].size < whole["lateral"].size * whole["depth"].size


def test_npz_map_of_a_moved_wall_is_in_the_files_coordinates(capture, tmp_path):
    """A wall at Z = 0.5 m (the fitted frame: y-tal's axes, origin on the wall): the map's axes
    carry the origin, so its best cell is the answer's argmax cell (0.5 m off before)."""
    import h5py
    moved = tmp_path / "moved.h5"
    shutil.copy(capture, moved)
    with h5py.File(moved, "r+") as f:
        for key in ("laser_grid_xyz", "sensor_grid_xyz", "laser_xyz", "sensor_xyz"):
            d = f[key][()]
            d[..., 2] += 0.5
            f[key][...] = d
    path = tmp_path / "m.npz"
    out = run("locate", str(moved), "--json", "--estimator", "paper", "--map", str(path))
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout)
    assert r["frame"]["origin"][2] == 0.5
    with np.load(path, allow_pickle=False) as m:
        score, axes = m["score"], [m[a] for a in m["axes"]]
        best = np.unravel_index(np.argmax(score), score.shape)
        cell = [a[i] for a, i in zip(axes, best)]
    assert np.allclose(cell, r["argmax_cell"], atol=1e-4), (cell, r["argmax_cell"])
