"""Measured-data tools: Eq. 26 calibration, background subtraction, photon counting."""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.io import calibration
from nlos_cl.physics.noise import PLANCK

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
    loc = nl.locate(nl.gauss_filter(calibrated), nl.Grid(), estimator="paper")
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
    clipped = nl.subtract_background(measured, bg, negatives="clip")
    assert clipped.data.min() >= 0 and clipped.data[0, 20] == pytest.approx(5.0, abs=1.1)
    kept = nl.subtract_background(measured, bg)  # the default keeps negatives
    assert kept.data.min() < 0
    np.testing.assert_array_equal(np.maximum(kept.data, 0), clipped.data)
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
    loc = nl.locate(nl.gauss_filter(a), nl.Grid(), estimator="paper")
    assert loc.error_m < 0.1


def test_tdc_bin_must_be_a_multiple_of_the_data_bin():
    with pytest.raises(nl.InputError, match="tdc_bin_s"):
        nl.PhotonCounter(tdc_bin_s=15e-12).expected_counts(hist_of(np.ones((3, 50))))


@pytest.mark.parametrize("scale_path, scale_time, unit", [
    (1, 1e9, "peak times in nanoseconds"),
    (1, 1e12, "peak times in picoseconds"),
    (100, 1, "paths in centimetres"),
    (100, 1e9, "paths in cm and times in ns"),  # the paper's own cm and ns
])
def test_calibration_in_other_units_names_the_likely_unit(scale_path, scale_time, unit):
    t = np.linspace(43e-9, 50e-9, 6)
    s = 0.297e9 * t - 12.691
    with pytest.raises(nl.InputError, match=unit) as info:
        nl.fit_calibration(s * scale_path, t * scale_time)
    assert "speed of light" in str(info.value) and "seconds" in str(info.value)


def test_calibration_a_little_off_c_is_accepted():
    t = np.linspace(43e-9, 50e-9, 6)
    assert nl.fit_calibration(1.3 * C * t - 12.0, t).speed_error == pytest.approx(0.3)


def csv(tmp_path, content, name="pairs.csv"):
    path = tmp_path / name
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    return path


PAIRS = [(2.5, 5.17e-8), (3.0, 5.34e-8), (3.5, 5.5e-8)]


@pytest.mark.parametrize("content", [
    "2.5,5.17e-8\n3.0,5.34e-8\n3.5,5.5e-8\n",
    "path_m,peak_time_s\n2.5,5.17e-8\n3.0,5.34e-8\n3.5,5.5e-8\n",
    "# measured 2024-05-02\npath;time\n2,5;5,17e-8\n3,0;5,34e-8\n3,5;5,5e-8\n",
    "2.5\t5.17e-8\n3.0  5.34e-8\n\n3.5 5.5e-8   # last\n",
    "\ufeffpath , time\r\n 2.5 , 5.17e-8\r\n3.0,5.34e-8\r\n3.5,5.5e-8\r\n",
    "Entfernung (m);Zeit (s, \xb5 genau)\n2.5;5.17e-8\n3.0;5.34e-8\n3.5;5.5e-8\n".encode("latin-1"),
])
def test_calibration_csv_variants_parse(tmp_path, content):
    paths, times = calibration.read_calibration_pairs(csv(tmp_path, content))
    assert np.allclose(paths, [p for p, _ in PAIRS]) and np.allclose(times, [t for _, t in PAIRS])


@pytest.mark.parametrize("content, message", [
    ("", "has no rows"),
    ("# nothing yet\n\n", "has no rows"),
    ("path,time\n", "has a header but no data rows"),
    ("2.5\n3.0\n3.5\n", "line 1: has 1 column(s), expected 2"),
    ("path\n2.5\n", "line 2: has 1 column(s)"),
    ("2.5,5.17e-8,7\n", "has 3 column(s)"),
    ("2.5,5.17e-8\n3.0,n/a\n", "line 2: ['3.0', 'n/a'] is not numeric"),
    (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "is not a text file"),
])
def test_bad_calibration_csv_is_a_clear_error(tmp_path, content, message):
    with pytest.raises(nl.InputError, match="Fix:") as info:
        calibration.read_calibration_pairs(csv(tmp_path, content))
    assert message in str(info.value), str(info.value)


def test_calibration_csv_missing_or_a_folder(tmp_path):
    for path in (tmp_path / "nope.csv", tmp_path):
        with pytest.raises(nl.InputError, match="does not exist or is not a file"):
            calibration.read_calibration_pairs(path)


def test_background_from_a_plain_ytal_file_is_accepted(runtime, tmp_path):
    """The signal keeps nlos_cl's exact axis (from its metadata); a background written by
    another tool has only y-tal's float32 fields, so its axis is rounded and its time origin
    differs. The bins are the same hidden paths: it must be accepted."""
    clean = nl.simulate(nl.paper_scene(facet_size_m=0.05),
                        nl.TimeAxis(2 * 20 / C + 25e-9, 10e-12, 1500), backend=runtime).histograms()
    background = clean.with_data(np.full(clean.data.shape, 1e-3 * clean.data.max()))
    nl.write_capture(tmp_path / "signal.h5", clean.with_data(clean.data + background.data))
    nl.write_capture(tmp_path / "bg.h5", background)
    import h5py
    with h5py.File(tmp_path / "bg.h5", "a") as f:
        del f["scene_info"]  # another tool: no nlos_cl metadata
    (signal,), (bg,) = nl.read_capture(tmp_path / "signal.h5"), nl.read_capture(tmp_path / "bg.h5")
    assert signal.time_axis != bg.time_axis  # exact vs float32-rounded, other time origin
    cleaned = nl.subtract_background(signal, bg)
    np.testing.assert_allclose(cleaned.data, clean.data, atol=1e-6 * clean.data.max())


def test_background_one_bin_off_is_refused():
    a = hist_of(np.ones((3, 50)))
    shifted = nl.HistogramSet(np.ones((3, 50)), nl.TimeAxis(10e-12, 10e-12, 50),
                              a.detector_spots, a.laser_spot, a.calibration)
    with pytest.raises(nl.InputError, match="background.time_axis: its bins lie 0.00") as info:
        nl.subtract_background(a, shifted)
    assert "m of hidden path away" in str(info.value)


def test_background_that_is_the_signal_itself_is_its_own_error():
    signal = hist_of(np.random.default_rng(0).random((3, 50)))
    with pytest.raises(nl.InputError, match="is the signal itself"):
        nl.subtract_background(signal, signal)
    with pytest.raises(nl.InputError, match="at least as strong as the signal in every bin"):
        nl.subtract_background(signal, signal.with_data(signal.data + 1.0))


def test_noise_models_share_one_interface():
    """AWGN and the photon counter both turn Signals into Signals through apply(signals, seed)."""
    scene = nl.paper_scene(facet_size_m=0.05)
    axis = nl.TimeAxis(2 * 20 / nl.SPEED_OF_LIGHT + 28e-9, 10e-12, 900)
    clean = nl.simulate(scene, axis, backend="reference")
    counter = nl.PhotonCounter(n_pulses=1e9, tdc_bin_s=50e-12)
    for model in (nl.AWGN(10.0), counter):
        noisy = nl.add_noise(clean, model=model, seed=3)
        again = nl.add_noise(clean, model=model, seed=3)
        assert isinstance(noisy, nl.Signals)
        assert np.array_equal(noisy.histograms().data, again.histograms().data)
    counts = nl.add_noise(clean, model=counter, seed=3).histograms()
    assert counts.time_axis.dt_s == pytest.approx(50e-12) and counts.data.min() >= 0
    assert np.array_equal(counts.data, np.round(counts.data))
    assert np.array_equal(counts.data, counter.counts(clean.histograms(), 3).data)
