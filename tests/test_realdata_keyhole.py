"""Keyhole imaging (measured, BSD-style; ../shared/realdata, skipped where absent): one
confocal wall spot, a retroreflective letter moved by a stage. Range only: each exposure's
range from nlos_cl.localization.ranges against the stage-derived range
(io/datasets/keyhole.py: sqrt((x - 0.5)^2 + (0.79 - z)^2), Demo.py's geometry).

Measured here: correlation 0.943 (E), 0.939 (K), 0.956 (Y), RMS after one constant offset
(+0.035 / +0.054 / +0.057 m) 0.025 / 0.034 / 0.027 m. Issue 21's goal (>= 0.95, <= 0.02 m) is
NOT met by this peak estimate; the bounds below guard what it does (a broken reader or time
zero gives correlations near 0), they are not the goal."""
from pathlib import Path

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.localization.ranges import confocal_range, confocal_ranges

KEYHOLE = Path(__file__).resolve().parents[2] / "shared" / "realdata" / "keyhole"


@pytest.mark.parametrize("letter", ["E", "K", "Y"])
def test_ranges_follow_the_stage(letter):
    folder = KEYHOLE / letter
    if not folder.is_dir():
        pytest.skip("../shared/realdata/keyhole is absent")
    frames, meta = nl.read_dataset(folder)
    ours, stage = confocal_ranges(frames), np.asarray(meta["stage_range_m"])
    offset = float(np.mean(ours - stage))
    assert np.corrcoef(ours, stage)[0, 1] > 0.9
    assert np.sqrt(np.mean((ours - stage - offset) ** 2)) < 0.05
    assert 0.0 < offset < 0.1  # ours a few cm beyond the stage's: the letter's face vs mount


def test_range_of_a_simulated_point_target(runtime):
    """A confocal histogram simulated by the forward model (laser and detection spot 1 mm
    apart) at a known range: the range is that distance, within a quarter of a 10 ps bin's
    path and the plate's half-size seen obliquely."""
    target = np.array([1.2, 1.6, 0.0])
    setup = nl.paper_setup(laser_spot=(0.0, 0.0, 0.0), detector_spots=[(1e-3, 0.0, 0.0)])
    scene = nl.Scene(setup, nl.Target(nl.rectangle(0.05, 0.05, centre=target,
                                                   normal=-target / np.linalg.norm(target),
                                                   cell_m=0.005)), 0.005, truth=target)
    h = nl.simulate(scene, nl.default_time_axis(setup, 1e-11), backend=runtime).histograms()
    confocal = nl.HistogramSet(h.data, h.time_axis, [(0.0, 0.0, 0.0)], [(0.0, 0.0, 0.0)],
                               h.calibration)
    assert confocal_range(confocal) == pytest.approx(np.linalg.norm(target), abs=0.005)


def test_range_only_needs_one_confocal_histogram():
    h = nl.HistogramSet(np.zeros((2, 10)), nl.TimeAxis(0, 1e-11, 10), np.zeros((2, 3)),
                        np.zeros(3), nl.PathCalibration(3e8, 0.0))
    with pytest.raises(nl.InputError, match="histograms: range-only"):
        confocal_range(h)
