"""Measured-data tools: Eq. 26 calibration, background subtraction, photon counting."""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.measured import PLANCK

C = nl.SPEED_OF_LIGHT


def test_calibration_recovers_the_papers_line():
    # paper Eq. 26: s(cm) = 29.7 t(ns) - 1269.1, RMSE 2.07 cm
    rng = np.random.default_rng(0)
    t = np.linspace(43e-9, 50e-9, 12)
    s = 0.297e9 * t - 12.691 + rng.normal(0, 0.02, t.size)
    fit = nl.fit_calibration(s, t)
    assert fit.calibration.a_m_per_s == pytest.approx(2.97e8, rel=0.01)
    assert fit.calibration.b_m[0] == pytest.approx(-12.691, abs=0.1)
    assert 0.01 < fit.rmse_m < 0.03 and fit.r2 > 0.99
    assert fit.speed_error == pytest.approx(-0.0093, abs=0.01)


@pytest.mark.parametrize("paths, times, field", [
    ([1, 2], [1e-9, 2e-9], "calibration pairs"),
    ([1, 2, 3], [1e-9, 2e-9], "calibration pairs"),
    ([1, 2, np.nan], [1e-9, 2e-9, 3e-9], "calibration pairs"),
    ([3, 2, 1], [1e-9, 2e-9, 3e-9], "slope"),
])
def test_bad_calibration_pairs(paths, times, field):
    with pytest.raises(nl.InputError, match=field):
        nl.fit_calibration(paths, times)


def test_calibrate_from_known_distances_then_locate(runtime):
    """As in the paper's Fig. 11: a target at known distances gives (path, peak time) pairs;
    the fitted line replaces the exact calibration, and a new position is located with it."""
    setup = nl.paper_setup()
    axis = nl.TimeAxis(2 * 20 / C + 10e-9, 10e-12, 3500)
    paths, times = [], []
    for y in (1.0, 1.5, 2.0, 2.5, 3.0):
        centre = np.array([1.0, y, 0.0])
        mesh = nl.rectangle(0.1, 0.1, centre=centre, normal=-centre / np.linalg.norm(centre),
                            cell_m=0.005)
        hist = nl.simulate(nl.Scene(setup, nl.Target(mesh), 0.005), axis, backend=runtime)
        paths.append(np.linalg.norm(centre) + np.linalg.norm(centre - setup.detector_spots[0]))
        times.append(nl.peak_times(hist.histograms())[0])
    fit = nl.fit_calibration(paths, times)
    assert fit.r2 > 0.9999 and fit.rmse_m < 0.005
    assert fit.calibration.a_m_per_s == pytest.approx(C, rel=2e-3)
    measured = nl.simulate(nl.paper_scene(), axis, backend=runtime).histograms()
    calibrated = nl.with_calibration(measured, fit.calibration)
    loc = nl.locate(nl.gauss_filter(calibrated), nl.Grid())
    assert loc.error_m < 0.05


def hist_of(data):
    return nl.HistogramSet(data, nl.TimeAxis(0.0, 10e-12, data.shape[1]),
                           nl.paper_setup().detector_spots, [0, 0, 0],
                           nl.PathCalibration(C, [0.0]))


def test_background_subtraction_modes():
    signal = np.zeros((3, 50))
    signal[:, 20] = 5.0
    background = np.full((3, 50), 2.0)
    background[:, 5] = 9.0  # an unstable background spike
    measured = hist_of(signal + background + np.linspace(-0.5, 0.5, 50))
    bg = hist_of(background + np.linspace(-0.5, 0.5, 50)[::-1])
    clipped = nl.subtract_background(measured, bg)
    assert clipped.data.min() >= 0 and clipped.data[0, 20] == pytest.approx(5.0, abs=1.1)
    kept = nl.subtract_background(measured, bg, negatives="keep")
    assert kept.data.min() < 0
    floored = nl.subtract_background(measured, bg, negatives="floor", floor=-0.1)
    assert floored.data.min() == pytest.approx(-0.1)
    assert np.array_equal(measured.data, signal + background + np.linspace(-0.5, 0.5, 50))


def test_background_of_another_shape_is_refused():
    with pytest.raises(nl.InputError, match="background"):
        nl.subtract_background(hist_of(np.ones((3, 50))), hist_of(np.ones((3, 40))))


def test_photon_counts_follow_the_detector_model(runtime):
    clean = nl.simulate(nl.paper_scene(facet_size_m=0.02),
                        nl.TimeAxis(2 * 20 / C + 28e-9, 10e-12, 900), backend=runtime).histograms()
    quiet = nl.PhotonCounter(dark_count_rate_hz=0, ambient_rate_hz=0, jitter_s=0, tdc_bin_s=50e-12)
    expected = quiet.expected_counts(clean)
    assert expected.time_axis.dt_s == pytest.approx(50e-12) and expected.data.shape == (3, 180)
    photon = PLANCK * C / quiet.wavelength_m
    energy = clean.data.sum(axis=1) * clean.time_axis.dt_s
    np.testing.assert_allclose(expected.data.sum(axis=1),
                               energy / photon * quiet.efficiency * quiet.n_pulses, rtol=1e-9)
    noisy = nl.PhotonCounter(jitter_s=50e-12)
    a, b = noisy.counts(clean, seed=3), noisy.counts(clean, seed=3)
    assert np.array_equal(a.data, b.data) and np.all(a.data == np.round(a.data))
    background_per_bin = (noisy.dark_count_rate_hz + noisy.ambient_rate_hz) * 50e-12 * noisy.n_pulses
    assert noisy.expected_counts(clean).data.min() == pytest.approx(background_per_bin, rel=1e-3)
    # Poisson: variance equals the mean; 12,000 background-only TDC bins pin the variance to
    # ~1.3 % (one standard error), so 5 % is a 4-sigma test
    many = nl.PhotonCounter(n_pulses=1e9, tdc_bin_s=50e-12).counts(
        hist_of(np.zeros((3, 20_000))), seed=1).data
    assert many.var() == pytest.approx(many.mean(), rel=0.05)
    loc = nl.locate(nl.gauss_filter(a), nl.Grid())
    assert loc.error_m < 0.1


def test_tdc_bin_must_be_a_multiple_of_the_data_bin():
    with pytest.raises(nl.InputError, match="tdc_bin_s"):
        nl.PhotonCounter(tdc_bin_s=15e-12).expected_counts(hist_of(np.ones((3, 50))))
