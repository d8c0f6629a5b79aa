"""Closed shapes among several targets (model.policy.closed_many): a box 0.6 m deep beside a
plate, seen by a 3 x 3 grid of spots 1.2 m across, K = 2 given. Its plate lies on its front face, the
box's centre 0.3 m behind; with the closed family fitted to both targets the box's centre is
found, and the plate stays (nearly) flat."""
import warnings

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.localization.model.policy import closed_many

BOX_CENTRE = (0.9, 2.6, 0.0)  # the paper's frame (y away from the wall), as nl.simulate's
PLATE_CENTRE = (-1.3, 2.2, 0.1)


@pytest.fixture(scope="module")
def frame():
    spots = [[x, 0.0, z] for x in (-0.5, 0.1, 0.7) for z in (-0.45, 0.05, 0.55)]
    setup = nl.paper_setup(detector_spots=spots)
    # nl.box(extents): sizes along x, y, z; 0.6 m along y is its depth seen from the wall
    solid = nl.Target(nl.box((0.5, 0.6, 0.8), centre=BOX_CENTRE, cell_m=0.01))
    flat = nl.Target(nl.rectangle(0.4, 0.6, centre=PLATE_CENTRE, normal=(0.0, -1.0, 0.0),
                                  cell_m=0.01))
    scene = nl.Scene(setup, solid, truth=BOX_CENTRE, more_targets=(flat,))
    clean = nl.simulate(scene, nl.default_time_axis(setup, 1e-12)).histograms()
    return nl.add_noise(clean, 20.0, seed=3).histograms()


def _located(frame):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return nl.locate_capture(frame, targets=2).points[0].location.targets


def _nearest(found, truth):
    return min(found, key=lambda t: np.linalg.norm(np.subtract(t.position, truth)))


def test_a_box_among_two_targets_is_found_at_its_centre(frame):
    found = _located(frame)
    box, flat = _nearest(found, BOX_CENTRE), _nearest(found, PLATE_CENTRE)
    assert box is not flat and box.fit.shape != "plate", box.fit.as_dict()
    assert np.linalg.norm(box.position - BOX_CENTRE) < 0.08
    assert np.linalg.norm(flat.position - PLATE_CENTRE) < 0.05
    assert box.fit.diagnostics["closed_tried"] is True


def test_without_closed_shapes_the_box_is_its_front_face(frame, monkeypatch):
    """The class the module fixes: plates only (closed_instead a no-op) put the box's centre
    on its front face, ~0.3 m (half its depth) in front of the truth."""
    monkeypatch.setattr(closed_many, "closed_instead", lambda problem, plates, nfev: plates)
    box = _nearest(_located(frame), BOX_CENTRE)
    assert box.fit.shape == "plate"
    assert np.linalg.norm(box.position - BOX_CENTRE) > 0.2


def test_the_default_locate_reports_the_box_and_the_plate(frame):
    """With no number of targets (the default: one, and more where the residual holds them,
    localization.separate), the closed answer for two targets is kept: separate reads each
    closed target's front face as its surface."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        found = nl.locate_capture(frame).points[0].location.targets
    assert len(found) == 2
    box = _nearest(found, BOX_CENTRE)
    assert box.fit.shape != "plate" and np.linalg.norm(box.position - BOX_CENTRE) < 0.08


def test_a_plate_given_a_depth_among_closed_targets_is_made_flat_again():
    """The K depths of a closed family pass the BIC test together, so a plate beside a box
    could keep a spurious depth (scenario occluders draw 47: an occluder fitted 0.11 m deep,
    its centre 0.057 m behind its face). _flat_where_unneeded holds each depth the data do not
    ask for at the family's least: here a plate fitted with its depth held at 0.11 m goes back
    to depth 0 on its face (within 5 mm), the box keeps its 0.45 m."""
    from nlos_cl.localization.estimate import Scored
    from nlos_cl.localization.model import ModelEstimator
    from nlos_cl.localization.model.forward.host_shapes import shape_problem
    from nlos_cl.localization.model.policy.closed_search import closed_free
    from nlos_cl.localization.model.shapes import box
    from nlos_cl.localization.model.solve.covariance import covariance
    from nlos_cl.localization.model.solve.fit import fit
    from nlos_cl.physics import layouts
    setup = nl.paper_setup(detector_spots=layouts.circle(centre=[-1.0, 0, 0], radius_m=0.6,
                                                         count=8))
    solid, face = (2.4, 3.0, 0.0), (1.5, 1.8, 0.2)
    scene = nl.Scene(setup, nl.Target(nl.box((0.45, 0.45, 0.9), centre=solid, cell_m=0.01)),
                     truth=solid, more_targets=(nl.Target(nl.rectangle(
                         0.5, 0.3, centre=face, normal=(-0.5, -0.866, 0.0), cell_m=0.01)),))
    raw = nl.add_noise(nl.simulate(scene, nl.default_time_axis(setup, 1e-12)), 20.0, seed=3)
    filtered = nl.gauss_filter(raw)
    est = ModelEstimator(targets=2)
    obs = est.observation(Scored(filtered.backend, None, nl.Grid(), False,
                                 filtered.n_detectors, filtered, raw))
    problem = est.problem(obs, filtered.backend)
    closed, free = shape_problem(problem, box), closed_free(np.ones(6, bool))
    rows = np.array([[*solid, 0.45, 0.9, 0.45, -np.pi], [*face, 0.5, 0.3, 0.11, -2.094]])
    held = np.full(rows.shape, np.inf)
    held[1, box.DEPTH] = 1e-4
    deep = fit(closed, rows, free, 30, prior=(rows, held))
    got, _ = closed_many._flat_where_unneeded(problem, closed, deep, free,
                                              covariance(closed, deep, free), 30)
    assert got.params[1, box.DEPTH] < 1e-3 < deep.params[1, box.DEPTH] - 0.1
    assert np.linalg.norm(box.front_of(got.params[1])[:3] - face) < 0.005
    assert got.params[0, box.DEPTH] > 0.3
