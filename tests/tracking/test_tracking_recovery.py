"""Re-acquisition (nlos_cl.tracking.recovery) on synthetic measurements (no simulation): a track
carried off by a velocity from one wrong first fit gets its target back under its own id, and
a measurement the track could not have reached does not take it over."""
import numpy as np

import nlos_cl as nl
from nlos_cl.localization.estimate import LocatedTarget
from nlos_cl.localization.fit_result import ModelFit, WarmStart
from nlos_cl.tracking import ConstantVelocity, Tracker, kalman, warm
from nlos_cl.tracking.association import screen
from nlos_cl.tracking.options import TrackRules

C = nl.SPEED_OF_LIGHT


def _layout():
    return nl.Layout(nl.TimeAxis(40 / C, 10e-12, 1024), np.array([[-0.5, 0, 0], [-1, 0, 0],
                     [-1.5, 0, 0]]), np.zeros(3), nl.PathCalibration(C, [-40.0]))


def _target(p, sigma):
    return LocatedTarget(np.asarray(p, float), np.diag([sigma ** 2, sigma ** 2, np.inf]), None)


def _a(k):
    return [2.0 + 0.05 * k, 2.0, 0]


def _b(k):
    return [4.0, 3.0 - 0.05 * k, 0]


def _run(reacquire, b_first=(4.6, 3.0, 0), frames=20):
    """Target b's first fit is 0.6 m off and its second is missing: the track's first update
    (frame 2) gives it ~3 m/s towards a, and it coasts away from b's right measurements (the
    crossings draws 5, 8, 18's failure)."""
    tr = Tracker(_layout(), estimator="paper", max_tracks=2, rules=TrackRules(reacquire=reacquire),
                 motion=ConstantVelocity(accel_sigma=0.5))
    seen = {"a": set(), "b": set()}
    for k in range(frames):
        b = list(b_first) if k == 0 else _b(k)
        tracks = tr.step([_target(_a(k), 0.01)] + ([] if k == 1 else [_target(b, 0.01)]), 0.1 * k)
        if k >= 5:
            for name, truth in (("a", _a(k)), ("b", _b(k))):
                near = min(tracks, key=lambda t: np.linalg.norm(t.position[:2] - truth[:2]))
                seen[name].add(near.id)
    return tr, tracks, seen


def test_a_lost_target_continues_its_coasting_track():
    _, _, before = _run(reacquire=False)
    assert len(before["b"]) > 1  # without re-acquisition: deleted, and born again
    tr, tracks, seen = _run(reacquire=True)
    assert seen == {"a": {1}, "b": {2}}
    (b,) = [t for t in tracks if t.id == 2]
    assert np.linalg.norm(b.position[:2] - np.array(_b(19))[:2]) < 0.02 and b.misses == 0
    smoothed = tr.smooth()[2]  # the restart splits the smoother's record: no NaN, every frame
    assert len(smoothed) == 20 and all(np.isfinite(s.position[:2]).all() for s in smoothed)
    assert np.linalg.norm(smoothed[-1].position[:2] - b.position[:2]) < 1e-9  # ends on filter


def test_a_measurement_the_track_could_not_reach_does_not_take_it_over():
    """The candidate 2.6 m from the track's last measured position, 0.3 s after it: outside the
    recovery gate (1 m/s speed prior), so no hand-over; the lost track is deleted as before."""
    tr = Tracker(_layout(), estimator="paper", max_tracks=2, motion=ConstantVelocity(0.5))
    for k in range(4):
        tr.step([_target(_a(k), 0.01), _target([4.0, 3.0, 0], 0.01)], 0.1 * k)
    for k in range(4, 12):
        tracks = tr.step([_target(_a(k), 0.01), _target([4.0, 0.4, 0], 0.01)], 0.1 * k)
    assert 2 not in {t.id for t in tracks}  # the far target is not track 2's


def test_measurements_with_no_measured_axis_are_screened_and_skip_the_gate_test():
    """A plate held at amplitude 0 has every variance infinite: no axis is measured. It is no
    measurement (screening drops it), and the warm-start gate test passes over it."""
    fit = ModelFit("plate", "upright plate", (), 1.0, np.zeros(3), "gauss", 0.0, 1, 1.0, False,
                   warm_start=WarmStart(True, 1.0, 5, 5, 0.01))
    src = nl.LocatedTarget(np.array([3.0, 2.0, 0.0]), np.diag([np.inf] * 3), fit=fit)
    m = kalman.measurement(src, 2, fallback_sigma_m=0.05, min_sigma_m=0.002)
    assert len(m.axes) == 0
    assert screen([m], max_sigma_m=0.5, max_birge_ratio=None, gate_probability=0.999) == []
    x, P = np.array([3.0, 2.0, 0.0, 0.0]), np.eye(4) * 1e-4
    assert not warm.outside_gates([m], [(None, x, P)], 0.999)


def test_two_targets_lost_at_once_each_continue_their_own_track():
    """Both tracks' fits jump 0.3 m at once (outside their gates, inside the recovery gates):
    two candidates at once, each handed to the track it could have come from."""
    tr = Tracker(_layout(), estimator="paper", max_tracks=2, motion=ConstantVelocity(0.5))
    for k in range(4):
        tr.step([_target(_a(k), 0.01), _target(_b(k), 0.01)], 0.1 * k)
    shift = np.array([0.0, 0.3, 0.0])
    for k in range(4, 10):
        tracks = tr.step([_target(np.add(_a(k), shift), 0.01),
                          _target(np.subtract(_b(k), shift), 0.01)], 0.1 * k)
    by_id = {t.id: t.position[:2] for t in tracks}
    assert sorted(by_id) == [1, 2]
    assert np.linalg.norm(by_id[1] - np.add(_a(9), shift)[:2]) < 0.02
    assert np.linalg.norm(by_id[2] - np.subtract(_b(9), shift)[:2]) < 0.02


def test_a_continued_track_keeps_its_misfit_floor_unless_the_candidate_brings_one():
    """recovery._continue: the model's misfit floor on these data (Prior.misfit) is the
    object's; a candidate fitted warm brings none and must not erase it."""
    from types import SimpleNamespace

    from nlos_cl.tracking.recovery import _continue
    track = SimpleNamespace(misfit=1.12)
    cand = SimpleNamespace(state=np.zeros(4), covariance=np.eye(4), plate=None, extra=[],
                           model="plate", misfit=None, late=False, offset=None)
    _continue(track, cand)
    assert track.misfit == 1.12
    _continue(track, SimpleNamespace(**dict(vars(cand), misfit=1.6)))
    assert track.misfit == 1.6
