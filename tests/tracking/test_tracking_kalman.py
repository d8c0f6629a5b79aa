"""The tracker on synthetic measurements (no simulation): smoothing, unobservable axes, gating,
track birth, confirmation and deletion, and identities through crossings."""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.localization.estimate import LocatedTarget
from nlos_cl.tracking import ConstantVelocity, Tracker
from nlos_cl.tracking.kalman import measurement
from nlos_cl.tracking.options import TrackRules

C = nl.SPEED_OF_LIGHT


def _layout():
    return nl.Layout(nl.TimeAxis(40 / C, 10e-12, 1024), np.array([[-0.5, 0, 0], [-1, 0, 0],
                     [-1.5, 0, 0]]), np.zeros(3), nl.PathCalibration(C, [-40.0]))


def _target(p, sigma=None, z_known=False):
    if sigma is None:
        return LocatedTarget(np.asarray(p, float))
    cov = np.diag([sigma ** 2, sigma ** 2, sigma ** 2 if z_known else np.inf])
    return LocatedTarget(np.asarray(p, float), cov)


def test_straight_line_is_smoothed():
    rng = np.random.default_rng(0)
    tr = Tracker(_layout(), estimator="paper", motion=ConstantVelocity(accel_sigma=0.01))
    raw, trk = [], []
    for k in range(60):
        t = 0.1 * k
        truth = np.array([2 + 0.5 * t, 1 + 0.3 * t, 0])
        z = truth + np.r_[0.03 * rng.standard_normal(2), 0]
        (track,) = tr.step([_target(z, 0.03)], t)
        if k >= 5:
            raw.append(np.linalg.norm(z - truth))
            trk.append(np.linalg.norm(track.position - truth))
    rms = lambda e: np.sqrt(np.mean(np.square(e)))  # noqa: E731
    assert rms(trk) <= 0.5 * rms(raw)
    assert track.status == "confirmed" and track.id == 1 and len(track.history) == 60
    np.testing.assert_allclose(track.velocity[:2], [0.5, 0.3], atol=0.05)


def test_paper_argmax_without_covariance_uses_the_fallback():
    m = measurement(_target([3, 2, 0]), 2, fallback_sigma_m=0.05, min_sigma_m=0.002)
    np.testing.assert_allclose(m.R, 0.0025 * np.eye(2))
    assert list(m.axes) == [0, 1]


def test_unobservable_height_is_not_updated():
    grid = nl.Grid.from_ranges(x=(0, 6), y=(0.1, 6), z=(-1, 1), step_m=0.5)
    tr = Tracker(_layout(), grid, estimator="paper")
    assert tr.dims == 3
    for k in range(10):  # the estimator reports z = 0.7 with an infinite variance
        (track,) = tr.step([_target([3, 2, 0.7], 0.01)], 0.1 * k)
    assert track.position[2] == pytest.approx(0.0)  # held on the grid's middle
    assert track.covariance[2, 2] > 1.0  # and still unknown
    assert np.isfinite(track.covariance).all()


def test_the_axis_a_vertical_line_cannot_see_is_not_measured():
    """Spots on a vertical line see no x (region.unseen_axis = 0): x is left out, z kept."""
    m = measurement(_target([3, 2, 0.4], 0.01, z_known=True), 3, fallback_sigma_m=0.05,
                    min_sigma_m=0.002, unseen_axis=0)
    assert list(m.axes) == [1, 2]
    np.testing.assert_allclose(m.z, [2.0, 0.4])
    m = measurement(_target([3, 2, 0.4]), 3, fallback_sigma_m=0.05, min_sigma_m=0.002,
                    unseen_axis=2)  # no covariance (the paper's argmax): the fallback's
    assert list(m.axes) == [0, 1]


def test_gate_rejects_an_outlier_and_tracks_are_deleted():
    tr = Tracker(_layout(), estimator="paper", rules=TrackRules(max_misses=3))
    for k in range(10):
        tr.step([_target([3, 2, 0], 0.01)], 0.1 * k)
    (track,) = tr.step([_target([5, 5, 0], 0.01)], 1.0)  # 3.6 m away: outside the gate
    assert np.linalg.norm(track.position[:2] - [3, 2]) < 0.05 and track.misses == 1
    for k in range(2):  # misses 2 and 3 of at most 3
        assert tr.step([], 1.1 + 0.1 * k) == [track]
    assert tr.step([], 1.3) == [] and track.status == "deleted" and tr.finished == [track]
    (new,) = tr.step([_target([5, 5, 0], 0.01)], 1.4)  # a new track is born
    assert new.id == 2 and new.status == "tentative"
    assert tr.step([], 1.5)[0].status == "tentative" and tr.step([], 1.6) == []  # 1 of 3 hits


def test_identities_survive_crossings():
    rng = np.random.default_rng(1)
    kept = 0
    for seed in range(10):
        rng = np.random.default_rng(seed)
        tr = Tracker(_layout(), estimator="paper", max_tracks=2,
                     motion=ConstantVelocity(accel_sigma=0.3))
        ids = {}
        for k in range(41):
            t = 0.1 * k
            a = np.array([2 + 0.5 * t, 2 + 0.5 * t, 0])  # crossing at (3, 3) at t = 2
            b = np.array([2 + 0.5 * t, 4 - 0.5 * t, 0])
            noisy = [p + np.r_[0.03 * rng.standard_normal(2), 0] for p in (a, b)]
            if np.linalg.norm(a - b) < 0.2:  # the estimator sees one target at the crossing
                noisy = [0.5 * (noisy[0] + noisy[1])]
            rng.shuffle(noisy)
            tracks = tr.step([_target(p, 0.03) for p in noisy], t)
            if k == 10:
                ids = {"a": min(tracks, key=lambda s: np.linalg.norm(s.position - a)).id,
                       "b": min(tracks, key=lambda s: np.linalg.norm(s.position - b)).id}
        final = {s.id: s.position for s in tracks}
        kept += (len(tracks) == 2 and ids["a"] != ids["b"]
                 and np.linalg.norm(final[ids["a"]] - a) < 0.15
                 and np.linalg.norm(final[ids["b"]] - b) < 0.15)
    assert kept >= 9


def test_bad_options():
    with pytest.raises(nl.InputError, match="motion.accel_sigma"):
        ConstantVelocity(accel_sigma=-1)
    with pytest.raises(nl.InputError, match="max_tracks"):
        Tracker(_layout(), estimator="paper", max_tracks=0)
    with pytest.raises(nl.InputError, match="confirm"):
        Tracker(_layout(), estimator="paper", rules=TrackRules(confirm=(3, 2)))
    tr = Tracker(_layout(), estimator="paper")
    tr.step([], 1.0)
    with pytest.raises(nl.InputError, match="t_s"):
        tr.step([], 0.5)


def _hidden(p, sd_m, hidden_sd_m):
    """A model fit's target: covariance sd_m, and a hidden part worth hidden_sd_m."""
    from types import SimpleNamespace
    fit = SimpleNamespace(hidden_sd_m=hidden_sd_m, birge_ratio=1.0, shape="box",
                          values=lambda: np.array([*p, 0.5, 0.5, 0.5, 0.0]), warm_start=None,
                          diagnostics={}, hidden_share=None)
    return LocatedTarget(np.asarray(p, float), np.diag([sd_m ** 2] * 3), details={"fit": 1},
                         fit=fit)


def test_a_partly_hidden_plate_weighs_what_its_hidden_part_leaves():
    """R gains the fit's hidden_sd_m^2 (ModelFit.hidden_sd_m): a plate fitted over its
    lit part, with a fitted sd of 3 mm but a centre that drifts along its hidden part, does not
    drag the track; the same drift with no hidden part is followed (the filter believes it)."""
    m = measurement(_hidden([3, 2, 0], 0.003, 0.1), 3, fallback_sigma_m=0.05, min_sigma_m=0.002)
    np.testing.assert_allclose(m.R, (0.003 ** 2 + 0.002 ** 2 + 0.01) * np.eye(3))
    errors = {}
    for hidden_sd_m in (0.0, 0.12):
        tr = Tracker(_layout(), estimator="paper", motion=ConstantVelocity(accel_sigma=0.1))
        for k in range(25):  # frames 20-24 drift 0.012 .. 0.06 m off (a crossing's few frames)
            t, truth = 0.1 * k, np.array([2 + 0.5 * 0.1 * k, 2.0, 0])
            drift = 0.0 if k < 20 else 0.012 * (k - 19)
            (track,) = tr.step([_hidden(truth + [0, drift, 0], 0.003,
                                        hidden_sd_m if drift else 0.0)], t)
        errors[hidden_sd_m] = np.linalg.norm(track.position - truth)
    assert errors[0.0] > 0.045  # followed the drift (0.06 m)
    assert errors[0.12] < 0.015  # held on its motion
