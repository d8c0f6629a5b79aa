"""Measured-data processing (nlos_cl.localization.measured), on synthetic captures whose truth
is known: a confocal 4 x 4 scan with an exGaussian direct return (sigma 30 ps, tau 80 ps),
a hidden return 2 m of path later, Poisson counts, a hot TDC bin, a dead bin and a time axis
declared 6 bins early; pile-up from first-photon detection; and the measured datasets
(../shared/realdata, skipped where absent)."""
import json
import math
from pathlib import Path

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.core.constants import SPEED_OF_LIGHT
from nlos_cl.core.errors import InputError
from nlos_cl.core.histograms import HistogramSet
from nlos_cl.core.paths import PathCalibration, TimeAxis
from nlos_cl.localization.measured import process_measured
from nlos_cl.localization.measured.bins import coates
from nlos_cl.localization.measured.lobe import lobe_centroid
from nlos_cl.localization.measured.response import exgauss

DT, N_BINS, SIGMA, TAU, SHIFT = 8e-12, 1200, 30e-12, 80e-12, 6
HOT, DEAD = 900, 945  # the dead bin inside the hidden return, where zeros are no chance
REAL = Path(__file__).resolve().parents[3] / "shared" / "realdata"


def _capture(seed=0, direct=True, shift=SHIFT, hot=True, dead=True):
    """A counts set: the direct return's peak at hidden path 0 belongs to bin 100;
    the file's t0 is declared `shift` bins early, so the peak shows `shift` bins late."""
    rng = np.random.default_rng(seed)
    u = np.linspace(-0.3, 0.3, 4)
    spots = np.array([(x, 0.0, z) for x in u for z in u])
    t = (np.arange(N_BINS) + 0.5) * DT
    mode_true = 100.5 * DT + shift * DT  # where the peak lands on the declared axis
    mu = mode_true - t[np.argmax(exgauss(t, 1.0, 0.0, SIGMA, TAU))]  # put the mode there
    wall = exgauss(t, 4e4 * DT, mu, SIGMA, TAU) if direct else np.zeros(N_BINS)
    hidden = 300.0 * np.exp(-0.5 * ((t - mode_true - 2.0 / SPEED_OF_LIGHT) / 60e-12) ** 2)
    lam = np.tile(wall + hidden + 0.5, (len(spots), 1))
    data = rng.poisson(lam).astype(float)
    if hot:
        data[:, HOT] += 200
    if dead:
        data[:, DEAD] = 0
    axis = TimeAxis(-100.5 * DT, DT, N_BINS)  # bin 100's centre at hidden path 0
    return HistogramSet(data, axis, spots, spots, PathCalibration(SPEED_OF_LIGHT, [0.0]))


def test_a_direct_return_gives_time_zero_the_response_and_the_gate():
    h = _capture()
    out = process_measured(h)
    rep = out.report
    json.dumps(rep)  # the CLI prints it
    tz = rep["time_zero"]
    assert tz["direct_return"] == "found" and tz["histograms"] == 16
    assert abs(tz["peak_shift_bins"] - SHIFT) < 0.5
    assert tz["action"].startswith("corrected t0")
    assert math.isclose(out.histograms.time_axis.t0_s, h.time_axis.t0_s - SHIFT * DT,
                        abs_tol=0.5 * DT)
    irf = rep["instrument_response"]
    assert irf["fit"] == "exGaussian"
    assert abs(irf["sigma_s"] / SIGMA - 1) < 0.2 and abs(irf["tau_s"] / TAU - 1) < 0.2
    assert math.isclose(out.h_from_response_s, 3 * irf["fwhm_s"] / 2.3548, rel_tol=1e-3)
    gate = rep["first_bounce_gate"]
    assert gate["applied"] and np.all(out.histograms.data[:, :gate["bins"]] == 0)
    assert gate["path_m"] < 1.5  # the hidden return at 2 m of path is kept
    k = int(np.argmax(out.histograms.data.sum(0)))
    path = out.histograms.path_axis().centres()[0, k]
    assert abs(path - 2.0) < 0.02  # ... at its true path, on the corrected axis
    assert rep["bins"]["kind"] == "counts"
    assert rep["bins"]["hot"] == [HOT] and rep["bins"]["dead"] == [DEAD]
    assert out.histograms.data[:, HOT].max() < 50 and out.histograms.data[:, DEAD].min() > 0
    assert h.data[0, HOT] > 150  # the user's set is not modified


def test_within_two_bins_the_files_time_zero_is_kept():
    out = process_measured(_capture(seed=1, shift=1))
    assert out.report["time_zero"]["action"].startswith("kept the file's t0")
    assert out.histograms.time_axis == _capture(seed=1, shift=1).time_axis


def test_a_calibration_keeps_time_zero_and_says_so():
    rep = process_measured(_capture(seed=2), calibrated=True).report["time_zero"]
    assert rep["action"].startswith("kept: the path calibration")


def test_without_a_direct_return_nothing_is_shifted_or_gated():
    h = _capture(seed=3, direct=False, hot=False, dead=False)
    out = process_measured(h)
    rep = out.report
    assert rep["time_zero"]["direct_return"].startswith("none")
    assert not rep["first_bounce_gate"]["applied"] and out.h_from_response_s is None
    assert np.array_equal(out.histograms.data, h.data)
    floats = process_measured(h.with_data(h.data * 1e-9)).report["bins"]
    assert floats["kind"] == "floats"


def test_one_histogram_is_not_checked_for_hot_bins():
    """A hot bin is hot in every histogram: with one, a one-bin return is not judged."""
    h = _capture(seed=4).select([0])
    assert process_measured(h).report["bins"]["hot"] == []


def test_coates_undoes_pile_up():
    """First-photon counts of 10^8 pulses at rates up to 0.05 photons per pulse and bin: the
    late bins lose ~47 % to pile-up; Coates gives the rates back within noise (~1 %)."""
    rng = np.random.default_rng(5)
    pulses = 100_000_000
    lam = 0.002 + 0.05 * np.exp(-0.5 * ((np.arange(64) - 20) / 4.0) ** 2)
    p = -np.expm1(-lam) * np.exp(-np.concatenate([[0.0], np.cumsum(lam)[:-1]]))
    counts = rng.multinomial(pulses, np.append(p, 1 - p.sum()))[:-1][None, :].astype(float)
    corrected, saturated = coates(counts, pulses)
    assert saturated == 0
    assert np.abs(corrected[0] / (pulses * lam) - 1).max() < 0.03
    assert (counts[0, 40:] / (pulses * lam[40:])).max() < 0.6  # what it corrected


def test_pulses_are_checked():
    h = _capture(seed=6)
    with pytest.raises(InputError, match="pulses"):
        process_measured(h, pulses=10)  # fewer than the photons counted
    with pytest.raises(InputError, match="pulses"):
        process_measured(h.with_data(h.data * 0.5 + 0.25), pulses=10**9)  # floats
    with pytest.raises(InputError, match="pulses"):
        process_measured(h, pulses=-3)
    rep = process_measured(h, pulses=10**9).report["pile_up"]
    assert rep["applied"] and rep["pulses"] == 10**9


def test_locate_capture_reports_each_step():
    h = _capture(seed=7, hot=False, dead=False)
    grid = nl.Grid((-0.2, 0.8, -0.2), (0.05, 0.05, 0.05), (9, 9, 9))
    found = nl.locate_capture(h, region=grid, estimator="paper")
    entry = found.as_json()
    steps = entry["processing"]
    assert set(steps) == {"pile_up", "bins", "time_zero", "instrument_response",
                          "background", "first_bounce_gate"}
    assert steps["instrument_response"]["h_source"].startswith("the direct return")
    assert math.isclose(found.h_s, steps["instrument_response"]["h_s"], rel_tol=1e-5)
    given = nl.locate_capture(h, region=grid, estimator="paper", h_s=0.65e-9)
    assert given.points[0].processing["instrument_response"]["h_source"] == "given"
    off = nl.locate_capture(h, region=grid, estimator="paper", preprocess=False)
    assert off.points[0].processing is None and off.h_s == 0.65e-9


def _real(path):
    if not path.exists():
        pytest.skip("../shared/realdata is absent")
    return nl.read_dataset(path)


def test_lct_has_a_cut_off_direct_return_and_is_gated():
    rep = process_measured(_real(REAL / "lct" / "data_s_u.mat")).report
    assert rep["time_zero"]["direct_return"] == "found" and "truncated" in rep["time_zero"]
    assert rep["time_zero"]["action"].startswith("kept")
    assert rep["instrument_response"]["measured"] == "tail only"
    assert rep["first_bounce_gate"]["applied"] and rep["bins"]["kind"] == "counts"


def test_ccsocr_is_gated_upstream():
    rep = process_measured(_real(REAL / "ccsocr-figure4" / "sparse")).report
    assert rep["time_zero"]["direct_return"].startswith("none")
    assert not rep["first_bounce_gate"]["applied"]


def test_the_lobe_centroid_follows_an_extended_return_not_its_brightest_part():
    """Two returns of one target (a near arm brighter than the rest, 12 bins further on)
    inside one lobe: the peak sits on the near arm, the centroid between them; a separate
    weaker return (below half the maximum between them) is left out; no return: the argmax."""
    t = np.arange(200.0)
    arm = lambda c, a: a * np.exp(-0.5 * ((t - c) / 4.0) ** 2)  # noqa: E731
    y = arm(80, 1.0) + arm(92, 0.8)
    assert int(np.argmax(y)) < 84
    assert 83.0 < lobe_centroid(y) < 86.0  # between the arms (their weighted mean is 85.3)
    assert lobe_centroid(y + arm(150, 0.3)) == pytest.approx(lobe_centroid(y), abs=1e-9)
    assert lobe_centroid(arm(50.3, 1.0)) == pytest.approx(50.3, abs=0.03)
    assert lobe_centroid(np.zeros(5)) == 0.0
    with pytest.raises(InputError, match="fraction"):
        lobe_centroid(y, fraction=1.5)
