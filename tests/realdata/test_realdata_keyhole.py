"""Keyhole imaging (measured, BSD-style; ../shared/realdata, skipped where absent): one
confocal wall spot, a retroreflective letter moved by a stage. Range only: each exposure's
range from nlos_cl.localization.ranges against the stage-derived range
(io/datasets/keyhole.py: sqrt((x - 0.5)^2 + 0.33^2 + (0.79 - z)^2), Demo.py's geometry; each
frame cropped at its own time zero, drifting between direct_before and direct_after).

Measured here (the main lobe's centroid, ranges.confocal_range): correlation 0.954 (E), 0.959
(K), 0.992 (Y), RMS after one constant offset (-0.020 / -0.023 / -0.006 m) 0.021 / 0.026 /
0.011 m (the peak gave 0.947 / 0.939 / 0.960 and 0.023 / 0.033 / 0.026 m). Issue 21's goal
(>= 0.95, <= 0.02 m) is met on Y only; the bounds below guard what it does (a broken reader or
time zero gives correlations near 0), they are not the goal."""
from pathlib import Path

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.localization.ranges import confocal_range, confocal_ranges

KEYHOLE = Path(__file__).resolve().parents[3] / "shared" / "realdata" / "keyhole"


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
    assert abs(offset) < 0.06  # the letter's bright part vs the centre of Demo.py's grid


def test_time_zero_follows_the_drift_and_the_truth_has_the_height():
    """E's direct return peaks 5 bins earlier before the scan than after it: the first frame
    is cropped that much earlier, the last at direct_after's peak; and the stage's range has
    Demo.py's 0.33 m between the spot's height and its object grid's centre."""
    folder = KEYHOLE / "E"
    if not folder.is_dir():
        pytest.skip("../shared/realdata/keyhole is absent")
    frames, meta = nl.read_dataset(folder)
    drift = meta["time_zero_drift_bins"]
    assert -6.0 < drift[0] < -4.0 and drift[-1] == 0.0
    assert np.all(np.diff(drift) > 0)  # linear in the frame index, from before to after
    x, z = np.asarray(meta["xpos_m"]), np.asarray(meta["zpos_m"])
    expected = np.sqrt((x - 0.5) ** 2 + 0.33 ** 2 + (0.79 - z) ** 2)
    np.testing.assert_allclose(meta["stage_range_m"], expected, atol=1e-12)
    assert frames[0][1].time_axis.t0_s == pytest.approx(-0.5 * 16e-12)  # peak bin centred


POINT_TARGET = np.array([1.2, 1.6, 0.0])


def _point_target_frame(runtime):
    """A confocal histogram simulated by the forward model (laser and detection spot 1 mm
    apart) of a 5 cm plate facing the spot at POINT_TARGET."""
    target = POINT_TARGET
    setup = nl.paper_setup(laser_spot=(0.0, 0.0, 0.0), detector_spots=[(1e-3, 0.0, 0.0)])
    scene = nl.Scene(setup, nl.Target(nl.rectangle(0.05, 0.05, centre=target,
                                                   normal=-target / np.linalg.norm(target),
                                                   cell_m=0.005)), 0.005, truth=target)
    h = nl.simulate(scene, nl.default_time_axis(setup, 1e-11), backend=runtime).histograms()
    return nl.HistogramSet(h.data, h.time_axis, [(0.0, 0.0, 0.0)], [(0.0, 0.0, 0.0)],
                           h.calibration), setup


def test_range_of_a_simulated_point_target(runtime):
    """The range is the point's distance, within a quarter of a 10 ps bin's path and the
    plate's half-size seen obliquely."""
    confocal, _ = _point_target_frame(runtime)
    assert confocal_range(confocal) == pytest.approx(np.linalg.norm(POINT_TARGET), abs=0.005)


def test_range_rules_of_a_simulated_point_target(runtime):
    """`reproduce real`'s diagnosis rules on a point's return: the peak at its range, the
    near and far half-height edges either side of it by half the filtered pulse's full width
    at half maximum (pulse and Gauss filter, sigma h / 3, added in quadrature: 2.3548 sigma of
    time, c / 2 of range per second), to 5 % (the 5 cm plate widens it a little)."""
    from nlos_cl.localization.ranges import range_rules
    from nlos_cl.core.constants import PAPER_H_S, SPEED_OF_LIGHT
    confocal, setup = _point_target_frame(runtime)
    rules = {k: float(v[0]) for k, v in range_rules([(0.0, confocal)], PAPER_H_S).items()}
    truth = float(np.linalg.norm(POINT_TARGET))
    assert rules["peak"] == pytest.approx(truth, abs=0.005)
    assert 0.5 * (rules["leading"] + rules["trailing"]) == pytest.approx(truth, abs=0.005)
    sigma_s = np.hypot(setup.pulse.sigma_s, PAPER_H_S / 3)
    width = 2.3548 * sigma_s * SPEED_OF_LIGHT / 2
    assert rules["trailing"] - rules["leading"] == pytest.approx(width, rel=0.05)


def test_range_only_needs_one_confocal_histogram():
    h = nl.HistogramSet(np.zeros((2, 10)), nl.TimeAxis(0, 1e-11, 10), np.zeros((2, 3)),
                        np.zeros(3), nl.PathCalibration(3e8, 0.0))
    with pytest.raises(nl.InputError, match="histograms: range-only"):
        confocal_range(h)
