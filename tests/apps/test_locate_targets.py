"""`nlos-cl locate`: every target with its uncertainty and its own truth (issue 56 item 2):
`simulate` keeps every target's truth in the capture, the answer lists each target with its
1-sigma per axis (or "unobservable"), matched to its truth by assignment, and every JSON answer
carries a covariance (the paper's argmax on a confocal capture: its likelihood's spread)."""
import itertools
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import nlos_cl as nl

SCENES = Path(__file__).resolve().parents[2] / "docs" / "scenes"


def run(*args):
    return subprocess.run([sys.executable, "-m", "nlos_cl.apps.cli", *args], check=False,
                          capture_output=True,
                          text=True, timeout=600)


@pytest.fixture(scope="module")
def two(tmp_path_factory):
    path = tmp_path_factory.mktemp("two") / "two.h5"
    out = run("simulate", str(SCENES / "two_targets.yaml"), "--out", str(path))
    assert out.returncode == 0, out.stderr
    return path


def test_simulate_keeps_every_targets_truth(two):
    [h] = nl.read_capture(two)
    assert h.truths is not None and np.allclose(h.truths, [[4, 2, 0], [2, 4, 0.2]])
    assert np.allclose(h.truth, h.truths[0])


def test_locate_lists_each_target_against_its_own_truth(two):
    out = run("locate", str(two), "--targets", "2", "--json")
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout)
    truths = np.array(r["truths"])
    assert truths.shape == (2, 3)
    targets = r["targets"]
    assert len(targets) == 2
    assert sorted(map(tuple, (t["truth"] for t in targets))) == sorted(map(tuple, truths))
    for t in targets:
        assert t["error_m"] == pytest.approx(np.linalg.norm(np.subtract(t["position"],
                                                                        t["truth"])), abs=1e-4)
        assert t["covariance"] is not None and len(t["sd_m"]) == 3 and t["shape"]
    # the assignment is the one of least total error (the other pairing costs more)
    pos = np.array([t["position"] for t in targets])
    costs = [sum(np.linalg.norm(pos[i] - truths[j]) for i, j in enumerate(p))
             for p in itertools.permutations(range(2))]
    assert sum(t["error_m"] for t in targets) == pytest.approx(min(costs), abs=1e-3)
    assert r["error_m"] == targets[0]["error_m"] and r["truth"] == targets[0]["truth"]
    text = run("locate", str(two), "--targets", "2")
    assert text.returncode == 0, text.stderr
    lines = [ln for ln in text.stdout.splitlines() if ln.strip().startswith("target ")]
    assert len(lines) == 2 and all("±" in ln and "truth" in ln and "error" in ln
                                   for ln in lines), text.stdout


def test_old_captures_stay_readable(tmp_path):
    """Files written before `truths`: simulate's metadata gives them, a bare truth is kept."""
    axis = nl.TimeAxis(0.0, 1e-11, 64)
    spots = [[-0.5, 0, 0], [-1, 0, 0.5], [-1, 0, -0.5]]
    h = nl.HistogramSet(np.ones((3, 64)), axis, spots, [0, 0, 0],
                        nl.PathCalibration(nl.SPEED_OF_LIGHT, [0.0]), truth=[4, 2, 0])
    old = nl.write_capture(tmp_path / "old.h5", h, metadata={"targets": [[4, 2, 0], [2, 4, 0]]})
    [back] = nl.read_capture(old)
    assert np.allclose(back.truths, [[4, 2, 0], [2, 4, 0]])
    bare = nl.write_capture(tmp_path / "bare.h5", h)
    [back] = nl.read_capture(bare)
    assert back.truths is None and np.allclose(back.truth, [4, 2, 0])


def _confocal_capture(path, runtime=None):
    """8 confocal histograms of a plate, each simulated with its own laser spot 1 mm from its
    detection point (the forward model refuses one spot for both), labelled confocal."""
    target = (3.0, 2.0, 0.0)
    scan = [(x, 0.0, z) for x in (-0.6, -0.2, 0.2, 0.6) for z in (-0.3, 0.3)]
    axis = nl.default_time_axis(nl.paper_setup(), 1e-11, max_hidden_path_m=9.0)
    mesh = nl.rectangle(0.3, 0.6, centre=target, normal=(-1.0, -1.0, 0.0), cell_m=0.02)
    rows = []
    for laser in scan:
        setup = nl.paper_setup(laser_spot=laser, detector_spots=[(laser[0] + 1e-3, 0, laser[2])])
        h = nl.simulate(nl.Scene(setup, nl.Target(mesh), 0.02, truth=target), axis).histograms()
        rows.append((h.data[0], h.calibration.offsets(1)[0], h.calibration.a_m_per_s))
    cal = nl.PathCalibration(rows[0][2], np.array([r[1] for r in rows]))
    assert np.allclose(cal.b_m, cal.b_m[0], atol=1e-9)
    h = nl.HistogramSet(np.array([r[0] for r in rows]), axis, scan, scan,
                        nl.PathCalibration(rows[0][2], [rows[0][1]]), truth=target)
    return nl.write_capture(path, nl.add_noise(h, 20.0, 1).histograms())


def test_confocal_argmax_carries_a_covariance_and_cli_advice(tmp_path):
    """The default on a confocal capture is the paper's argmax: its JSON answer has a finite
    covariance (the likelihood's spread), and the advice is spelled as the command line's."""
    path = _confocal_capture(tmp_path / "conf.h5")
    out = run("locate", str(path), "--json")
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout)
    assert r["estimator"] == "paper" and r["targets"]
    for t in r["targets"]:
        assert t["covariance"] is not None or t["unobservable"], t
        assert all(sd is None or sd > 0 for sd in t["sd_m"]) and t.get("uncertainty") != \
            "the estimator gives no covariance"
    assert "--estimator model" in out.stderr and "estimator='model'" not in out.stderr
    assert "slower" in out.stderr
