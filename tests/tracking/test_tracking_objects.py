"""One object, one track (tracking.association.objects): plate fits that touch are one object's
faces or light, and start one track that carries the others as its extra plates; on
synthetic fits (no simulation)."""
import numpy as np

import nlos_cl as nl
from nlos_cl.localization.estimate import LocatedTarget
from nlos_cl.localization.fit_result import ModelFit, Parameter
from nlos_cl.tracking import ConstantVelocity, Tracker, association, kalman, warm
from nlos_cl.tracking.births import TargetCount

C = nl.SPEED_OF_LIGHT
NAMES = ("x", "y", "z", "width", "height", "yaw")


def _layout():
    return nl.Layout(nl.TimeAxis(40 / C, 10e-12, 1024), np.array([[-0.5, 0, 0], [-1, 0, 0],
                     [-1.5, 0, 0], [-1, 0, 0.5]]), np.zeros(3), nl.PathCalibration(C, [-40.0]))


def _plate(x, y, z, width, height, amplitude=1.0, sigma=0.02):
    """A plate fit's located target, facing the wall (scenario draw 80's frame 0: a thin plate
    on a person's front, a wide flat one on his late light)."""
    row = (x, y, z, width, height, -np.pi / 2)
    fit = ModelFit("plate", "upright plate", tuple(Parameter(n, v) for n, v in zip(NAMES, row)),
                   amplitude, np.array([0.0, -1.0, 0.0]), "gauss", 100.0, 500, 1.5, True)
    return LocatedTarget(np.array([x, y, z], float), np.diag([sigma ** 2] * 3), None, fit=fit)


def _person(k):
    """Frame k of a person walking along the wall, fitted as two touching plates: his front
    (thin, tall, bright) and a wide flat plate on his late light lagging beside it."""
    x = -0.6 + 0.1 * k
    return [_plate(x, 2.17, -0.1, 0.13, 1.2, amplitude=180.0),
            _plate(x - 0.4, 2.17, 0.2, 1.04, 0.19, amplitude=95.0)]


def _tracker(max_tracks=3):
    """A tracker counting its targets (`nlos-cl track`'s default: the model fit, 'auto')."""
    from nlos_cl.localization.model import ModelEstimator
    tr = Tracker(_layout(), estimator=ModelEstimator(targets="auto", max_targets=max_tracks),
                 max_tracks=max_tracks, motion=ConstantVelocity(accel_sigma=0.5))
    assert tr.count is not None
    return tr


def test_a_given_number_of_targets_is_not_made_fewer_objects():
    """With K given (`--targets 2`), two touching plates are two targets, as before."""
    tr = Tracker(_layout(), estimator="paper", max_tracks=2,
                 motion=ConstantVelocity(accel_sigma=0.5))
    for k in range(4):
        tracks = tr.step(_person(k), 0.1 * k)
    assert len(tracks) == 2


def test_a_target_fitted_as_touching_plates_gets_one_track_which_carries_both():
    """Before, each plate of one person started a track of its own: two confirmed tracks
    followed him (scenario clutter draw 80, 'found 2 of 1')."""
    tr = _tracker()
    for k in range(6):
        tracks = tr.step(_person(k), 0.1 * k)
    (track,) = tracks
    assert track.status == "confirmed"
    assert abs(track.position[0] - (-0.6 + 0.5)) < 0.05  # the bright front, not the mean
    assert len(track.extra) == 1 and abs(track.extra[0][3] - 1.04) < 1e-9


def test_plates_apart_are_two_objects_and_two_tracks():
    tr = _tracker()
    for k in range(6):
        x = -0.6 + 0.1 * k
        tracks = tr.step([_plate(x, 2.2, 0.0, 0.3, 0.5), _plate(x + 2.0, 3.5, 0.0, 0.3, 0.5)],
                         0.1 * k)
    assert len(tracks) == 2 and all(t.status == "confirmed" and not t.extra for t in tracks)


def test_two_tracks_whose_plates_touch_keep_their_own():
    """Two followed targets side by side (a crossing) are not made one object."""
    tr = _tracker()
    for k in range(4):  # apart: 2.0 m .. 1.4 m between centres
        tr.step([_plate(-1.0 + 0.1 * k, 2.2, 0.0, 1.0, 0.5), _plate(1.0 - 0.1 * k, 2.2, 0.0,
                 1.0, 0.5)], 0.1 * k)
    pair = [_plate(-0.55, 2.2, 0.0, 1.0, 0.5), _plate(0.55, 2.2, 0.0, 1.0, 0.5)]
    assert association.count_objects([_measured(p) for p in pair]) == 1  # now they touch
    tracks = tr.step(pair, 0.4)
    assert len(tracks) == 2 and all(t.misses == 0 and not t.extra for t in tracks)


def _measured(target):
    return kalman.measurement(target, 2, fallback_sigma_m=0.05, min_sigma_m=0.002)


def test_the_warm_fit_counts_and_moves_a_tracks_extra_plates():
    tr = _tracker()
    for k in range(3):
        tr.step(_person(k), 0.1 * k)
    (track,) = tr.tracks
    assert TargetCount(3).for_frame([track]) == (2, 2)
    (prediction,) = kalman.predict_tracks([track], 0.3, tr.motion)
    assert warm.starters([prediction], 2, tentative=True) is not None
    prior = warm.prior([prediction])
    shift = prior.rows[0, :2] - track.plate[:2]
    assert prior.rows.shape == (2, 6)
    np.testing.assert_allclose(prior.rows[1, :2] - track.extra[0][:2], shift)
    np.testing.assert_allclose(prior.measured[1], track.extra[0])
    assert np.isinf(prior.size_sd[1]).all()


def test_a_counted_fits_plate_that_no_track_took_rides_with_the_carrier():
    """A fit of the tracks' own plates (no 'auto') finds no new target: its extra plate
    moved off its track's object still belongs to that track, not to a birth."""
    front = _person(0)[0]
    track = _tracker().lifecycle.birth(_measured(front), 0.0, 0)
    track.extra = [np.zeros(6)]
    m_front, far = _measured(front), _measured(_plate(-2.6, 1.7, 0.2, 0.8, 0.04))
    free, extras = association.objects([(track, m_front)], [far], [track])
    assert free == [] and len(extras[id(m_front)]) == 1
    free, extras = association.objects([(track, m_front)], [far], [])
    assert free == [far] and not extras


def test_while_a_track_misses_a_plate_touching_another_is_not_taken_as_its_face():
    """A followed target lost from its gate (a crossing) may be the free plate beside another
    track's: it is left free (recovery may re-find it), not made that track's extra plate."""
    tr = _tracker()
    for k in range(4):
        tr.step([_plate(-1.0 + 0.1 * k, 2.2, 0.0, 1.0, 0.5), _plate(1.5, 3.5, 0.0, 1.0, 0.5)],
                0.1 * k)
    pair = [_plate(-0.6, 2.2, 0.0, 1.0, 0.5), _plate(0.2, 2.2, 0.0, 1.0, 0.5)]  # B: missed
    assert association.count_objects([_measured(p) for p in pair]) == 1
    tracks = tr.step(pair, 0.4)
    assert not any(t.extra for t in tracks) and len(tracks) == 3  # free: a birth may take it
