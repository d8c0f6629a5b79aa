"""A located target's shadow from the laser spot (localization.shadow): the segment test on
plates and boxes, the box a fit gives, and the JSON in a moved frame hiding the same points."""
from types import SimpleNamespace

import numpy as np
import pytest

from nlos_cl.core.grid import Grid
from nlos_cl.io.ytal.frames import CaptureFrame
from nlos_cl.localization.estimate import LocatedTarget
from nlos_cl.localization.shadow import crosses, shadows

LASER = np.zeros(3)


def _plate(centre, w=0.6, h=0.4, shape="plate", depth=0.0):
    """A fitted target facing the laser spot (our frame: y away from the wall)."""
    n = -np.asarray(centre, float)
    n[2] = 0.0
    fit = SimpleNamespace(normal=n / np.linalg.norm(n), shape=shape, as_dict=dict)
    return LocatedTarget(np.asarray(centre, float), extent_m=np.array([w, h, depth]), fit=fit)


def test_a_plate_hides_what_lies_behind_it_and_nothing_else():
    (s,) = shadows([_plate([0.0, 1.0, 0.0])], LASER)
    behind = [[0.0, 3.0, 0.0], [0.5, 2.0, 0.3], [-0.55, 2.0, -0.35]]  # within 0.3 x 0.2 at 1 m
    beside = [[1.0, 2.0, 0.0], [0.0, 2.0, 0.5], [0.0, 0.5, 0.0], [0.0, 1.0, 0.0]]
    assert s.hides(behind).all()
    assert not s.hides(beside).any()  # off the cone, before the plate, on it


def test_a_box_hides_from_its_far_side_on():
    box = _plate([0.0, 2.0, 0.0], w=0.4, h=0.4, shape="box", depth=0.4)
    (s,) = shadows([box], LASER)
    assert s.hides([[0.0, 2.3, 0.0], [0.0, 4.0, 0.1]]).all()
    assert not s.hides([[0.0, 2.1, 0.0]]).any()  # inside the box: the target itself


def test_no_shadow_without_a_size_or_a_single_laser_spot():
    argmax = LocatedTarget(np.array([0.0, 1.0, 0.0]))
    assert shadows([argmax], LASER) == []
    assert shadows([_plate([0.0, 1.0, 0.0])], np.zeros((4, 3))) == []  # paired spots


def test_the_json_in_a_moved_frame_hides_the_same_points_moved():
    """Any rigid frame: the declared apex and box, moved, hide exactly the points moved."""
    a = np.deg2rad(35.0)
    m = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    frame = CaptureFrame("moved", ("X", "Y", "Z"), m @ np.array([[1, 0, 0], [0, 0, 1],
                                                                  [0, -1, 0]]), "test",
                         (1.0, -2.0, 0.5))
    (s,) = shadows([_plate([0.3, 1.5, 0.2])], LASER)
    region = Grid.from_ranges((-2, 2), (0.1, 4), (-1, 1), step_m=0.1)
    j = s.as_json(frame, region)
    pts = np.random.default_rng(0).uniform([-2, 0.1, -1], [2, 4, 1], (4000, 3))
    ours = s.hides(pts)
    box = j["box"]
    theirs = crosses(j["apex"], frame.from_internal(pts), np.asarray(box["centre"]),
                     box["axes"], box["half_m"])
    assert ours.sum() > 50 and np.array_equal(ours, theirs)
    lo, hi = np.transpose(j["region_part_m"])
    inside = frame.from_internal(pts[ours])
    assert np.all(inside >= lo - 0.25) and np.all(inside <= hi + 0.25)


@pytest.mark.parametrize("shape, kept", [("cylinder", np.sqrt(0.5)),
                                         ("ellipsoid", np.sqrt(1 / 3))])
def test_a_curved_target_claims_only_its_inscribed_box(shape, kept):
    (s,) = shadows([_plate([0.0, 2.0, 0.0], w=0.4, h=0.4, shape=shape, depth=0.4)], LASER)
    assert s.half == pytest.approx([0.2 * kept, 0.2 * (1.0 if shape == "cylinder" else kept),
                                    0.2 * kept])


def test_a_located_plate_declares_a_shadow_that_the_light_really_misses():
    """A 0.6 m plate located with no option: a 0.15 m square put in its declared shadow adds
    (almost) nothing to the noise-free histograms, one put beside the shadow adds its light:
    the shadow declared is physically true."""
    import nlos_cl as nl
    from nlos_cl.physics import layouts
    setup = nl.paper_setup(detector_spots=layouts.circle((-1.0, 0.0, 0.0), 0.5, 8))
    axis = nl.default_time_axis(setup, 10e-12)

    def square(centre, w):
        return nl.Target(nl.rectangle(centre=centre, width_m=w, height_m=w,
                                      normal=(-0.3, -1.0, 0.0), cell_m=0.02))
    plate = square((0.4, 1.2, 0.0), 0.6)
    hist = nl.add_noise(nl.simulate(nl.Scene(setup, plate, 0.02), axis), 20.0,
                        seed=3).histograms()
    (s,) = nl.locate_capture(hist).points[0].as_json()["shadowed"]
    box = s["box"]
    behind = np.array([0.8, 2.4, 0.0])  # 2x the plate's distance, on the ray O -> plate
    beside = np.array([-0.8, 2.4, 0.0])
    assert crosses(s["apex"], behind, np.asarray(box["centre"]), box["axes"], box["half_m"])[0]
    assert not crosses(s["apex"], beside, np.asarray(box["centre"]), box["axes"],
                       box["half_m"])[0]
    alone = nl.simulate(nl.Scene(setup, plate, 0.02), axis).histograms().data

    def added(p):
        both = nl.Scene(setup, plate, 0.02, more_targets=(square(p, 0.15),))
        own = nl.simulate(nl.Scene(setup, square(p, 0.15), 0.02), axis).histograms().data
        return np.abs(nl.simulate(both, axis).histograms().data - alone).sum() / np.abs(own).sum()
    with pytest.warns(UserWarning, match="hidden from detector"):  # the simulator agrees
        assert added(behind) < 0.05
    assert added(beside) > 0.9
