"""The tracker's offline smoother, measurement screening and ambiguous association, on synthetic
measurements (no simulation), and the fixed-level sensor noise used for cluttered scenes."""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.localization.estimate import LocatedTarget
from nlos_cl.localization.fit_result import ModelFit
from nlos_cl.tracking import ConstantVelocity, SensorNoise, Tracker
from nlos_cl.tracking.association import screen
from nlos_cl.tracking.kalman import measurement
from nlos_cl.tracking.options import MeasurementNoise

C = nl.SPEED_OF_LIGHT


def _layout():
    return nl.Layout(nl.TimeAxis(40 / C, 10e-12, 1024), np.array([[-0.5, 0, 0], [-1, 0, 0],
                     [-1.5, 0, 0]]), np.zeros(3), nl.PathCalibration(C, [-40.0]))


def _target(p, sigma, birge=None):
    cov = np.diag([sigma ** 2, sigma ** 2, np.inf])
    fit = None if birge is None else ModelFit("plate", "upright plate", (), 1.0, np.zeros(3),
                                              "gauss", 0.0, 1, birge, False)
    return LocatedTarget(np.asarray(p, float), cov, None, fit=fit)


def _rms(e):
    return float(np.sqrt(np.mean(np.square(e))))


def test_smoother_halves_the_per_frame_error_and_ends_on_the_filter():
    rng = np.random.default_rng(0)
    tr = Tracker(_layout(), estimator="paper", motion=ConstantVelocity(accel_sigma=0.047))
    truths, raw, filtered = [], [], []
    for k in range(50):
        t = 0.1 * k
        truth = np.array([2 + 0.2 * t, 1 + 0.3 * t, 0])
        z = truth + np.r_[0.008 * rng.standard_normal(2), 0]
        (track,) = tr.step([_target(z, 0.008)], t)
        if k == 10:
            filtered_var = np.diag(track.position_covariance)[:2]
        truths.append(truth)
        raw.append(np.linalg.norm(z[:2] - truth[:2]))
        filtered.append(np.linalg.norm(track.position[:2] - truth[:2]))
    points = tr.smooth()[1]
    assert [p.frame for p in points] == list(range(50))
    smoothed = [np.linalg.norm(p.position[:2] - truths[p.frame][:2]) for p in points]
    # the last frame has no later frames: smoothed == filtered there (RTS's boundary)
    np.testing.assert_allclose(points[-1].position[:2], track.position[:2], atol=1e-12)
    # measured on this seed: smoother 0.42 x per-frame, filter 0.69 x; white noise and the
    # motion model's own data, so the bound 0.5 only fails if the smoother is broken
    assert _rms(smoothed[5:]) <= 0.5 * _rms(raw[5:])
    assert _rms(smoothed[5:]) < 0.8 * _rms(filtered[5:])
    # knowing the later frames can only narrow a frame's uncertainty (RTS: P_k|N <= P_k|k)
    assert np.all(np.diag(points[10].covariance)[:2] < filtered_var)


def test_fixed_lag_equals_the_full_smoother_at_that_frame():
    """Tracker.lagged(L) after frame k is the RTS smoother's frame k - L as the full record
    would give it then (the backward pass needs no frame older than k - L), and lag 0 is the
    filter's own state."""
    rng = np.random.default_rng(3)
    tr = Tracker(_layout(), estimator="paper", motion=ConstantVelocity(accel_sigma=0.047))
    lag = 4
    for k in range(30):
        t = 0.1 * k
        z = np.array([2 + 0.2 * t, 1 + 0.3 * t, 0]) + np.r_[0.008 * rng.standard_normal(2), 0]
        (track,) = tr.step([_target(z, 0.008)], t)
        np.testing.assert_allclose(tr.lagged(0)[1].position, track.position, atol=1e-12)
        point = tr.lagged(lag)[1]
        assert point.frame == max(k - lag, 0)
        full = {p.frame: p for p in tr.smooth()[1]}  # everything up to frame k
        np.testing.assert_allclose(point.position, full[point.frame].position, atol=1e-10)
        np.testing.assert_allclose(point.covariance[:2, :2],
                                   full[point.frame].covariance[:2, :2], atol=1e-14)
    with pytest.raises(nl.InputError, match="lag"):
        tr.lagged(-1)


def test_screen_drops_misfits_and_vague_measurements_and_merges_duplicates():
    kw = dict(fallback_sigma_m=0.05, min_sigma_m=0.002)
    ms = [measurement(_target(p, s, b), 2, **kw) for p, s, b in [
        ([3, 2, 0], 0.01, 1.1), ([3.004, 2.003, 0], 0.01, 1.1),  # one target fitted twice
        ([4, 1, 0], 0.01, 9.0),  # a fit that leaves 9x the noise unexplained
        ([2, 3, 0], 1.5, 1.0)]]  # a spare plate on noise: sd 1.5 m
    kept = screen(ms, max_sigma_m=0.5, max_birge_ratio=2.0, gate_probability=0.999)
    assert len(kept) == 1
    np.testing.assert_allclose(kept[0].z, [3.002, 2.0015], atol=1e-9)  # equal weights: the mean
    everything = screen(ms, max_sigma_m=None, max_birge_ratio=None, gate_probability=0.999)
    assert len(everything) == 3  # only the duplicate merged


def test_one_blob_for_two_tracks_updates_neither():
    tr = Tracker(_layout(), estimator="paper", max_tracks=2,
                 motion=ConstantVelocity(accel_sigma=0.1))
    a = lambda k: [3, 2.3 + 0.04 * k, 0]  # noqa: E731  (two targets crossing at k = 5)
    b = lambda k: [3, 2.7 - 0.04 * k, 0]  # noqa: E731
    for k in range(5):
        tr.step([_target(a(k), 0.02), _target(b(k), 0.02)], 0.1 * k)
    ids = {t.id: t.position[1] < 2.5 for t in tr.tracks}  # which one is a
    tracks = tr.step([_target([3, 2.5, 0], 0.02)], 0.5)  # one blob, inside both gates
    assert len(tracks) == 2 and all(t.misses == 1 for t in tracks)  # both coast
    for k in (6, 7):
        tracks = tr.step([_target(a(k), 0.02), _target(b(k), 0.02)], 0.1 * k)
    for t in tracks:  # the one that was below is now above: identities kept
        assert (t.position[1] > 2.5) == ids[t.id] and t.misses == 0


def test_two_plates_on_one_spot_update_no_track_while_two_are_alive():
    # the degenerate two-target fit: both plates on one spot, near one target (0.15 m: inside
    # its gate alone) and far from the other
    pair = [_target([3, 2.5, 0], 0.01), _target([3.002, 2.501, 0], 0.01)]
    two = Tracker(_layout(), estimator="paper", max_tracks=2,
                  motion=ConstantVelocity(accel_sigma=0.1))
    for k in range(3):
        two.step([_target([3, 2.35, 0], 0.05), _target([3, 2.95, 0], 0.05)], 0.1 * k)
    for k in range(3, 6):
        tracks = two.step(pair, 0.1 * k)
    assert len(tracks) == 2 and all(t.misses == 3 for t in tracks)  # the pair stays unused
    assert sorted(abs(t.position[1] - 2.65) for t in tracks) == pytest.approx([0.3, 0.3],
                                                                              abs=0.05)
    one = Tracker(_layout(), estimator="paper", motion=ConstantVelocity(accel_sigma=0.1))
    for k in range(3):  # one target fitted twice: it is that target
        (track,) = one.step(pair, 0.1 * k)
    assert track.status == "confirmed" and track.misses == 0


def test_sensor_noise_level_does_not_follow_the_scene():
    axis = nl.TimeAxis(40 / C, 10e-12, 4096)
    t = np.arange(4096)
    target = 1e-12 * np.exp(-0.5 * ((t - 1000) / 30.0) ** 2) * np.ones((3, 1))
    box = 50 * 1e-12 * np.exp(-0.5 * ((t - 500) / 30.0) ** 2) * np.ones((3, 1))
    h = lambda d: nl.HistogramSet(d, axis, [[-0.5, 0, 0], [-1, 0, 0], [-1.5, 0, 0]],  # noqa
                                  [0, 0, 0], nl.PathCalibration(C, [-40.0]))
    noise = SensorNoise.from_snr(h(target), 10)
    expected = np.sqrt(np.mean(target ** 2, axis=1) / 10)
    np.testing.assert_allclose(noise.sigma_w, expected, rtol=1e-12)
    alone = noise.apply(nl.upload(h(target)), 3).histograms().data
    cluttered = noise.apply(nl.upload(h(target + box)), 3).histograms().data
    # the same draw on both: the box adds its own signal and nothing to the noise (float32
    # storage: 1e-6 of the box's peak)
    np.testing.assert_allclose(cluttered - alone, box, atol=1e-6 * box.max())
    # and the level is the one asked for: the sd of 4,096 draws is within 4.5 standard errors
    # (1 / sqrt(2 * 4096) = 1.1 % each)
    np.testing.assert_allclose(np.std(alone - target, axis=1), expected, rtol=0.05)


def test_bad_sensor_noise_and_screening_options():
    with pytest.raises(nl.InputError, match="sigma_w"):
        SensorNoise(-1.0)
    with pytest.raises(nl.InputError, match="sigma_w"):
        SensorNoise("loud")
    with pytest.raises(nl.InputError, match="max_birge_ratio"):
        Tracker(_layout(), estimator="paper", noise=MeasurementNoise(max_birge_ratio=0))
    with pytest.raises(nl.InputError, match="max_sigma_m"):
        Tracker(_layout(), estimator="paper", noise=MeasurementNoise(max_sigma_m=-0.5))
