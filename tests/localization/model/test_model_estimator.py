"""The model-based estimator (nlos_cl.localization.model) end to end: data from nl.simulate at the library's
defaults (1 cm facets, 1 ps bins), located by fitting a coarse plate model."""
import math
import subprocess
import sys
import warnings

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.localization.model import HEIGHT_WARNING, ModelEstimator, height_observable, plate_facets

GRID = nl.Grid.from_ranges(x=(0, 6), y=(0.01, 6), step_m=0.02)
TRIANGLE = [[-0.5, 0, 0], [-1.0, 0, 0.5], [-1.0, 0, -0.5]]
CIRCLE8 = [[-1.0 + 0.5 * math.cos(a), 0.0, 0.5 * math.sin(a)] for a in np.arange(8) * math.pi / 4]


def frame(position, size=(0.3, 1.6), spots=None, seed=0, normal=(-1, 0, 0)):
    setup = nl.paper_setup() if spots is None else nl.paper_setup(detector_spots=spots)
    mesh = nl.rectangle(size[0], size[1], centre=position, normal=normal)
    signals = nl.simulate(nl.Scene(setup, nl.Target(mesh), truth=position))
    noisy = nl.add_noise(signals, 10, seed=seed)
    return nl.gauss_filter(noisy), noisy


def test_paper_scene_centre_size_and_covariance():
    filtered, noisy = frame((4.0, 2.0, 0.0))
    with pytest.warns(UserWarning, match="height"):
        loc = nl.locate(filtered, GRID, estimator="model", raw=noisy)
    assert loc.estimator == "model" and loc.error_m < 0.02
    target = loc.targets[0]
    assert abs(target.extent_m[0] - 0.3) < 0.1 and abs(target.extent_m[1] - 1.6) < 0.3
    cov = target.covariance
    assert cov.shape == (3, 3) and np.all(np.isfinite(cov[:2, :2]))
    assert np.all(np.linalg.eigvalsh(cov[:2, :2]) > 0)
    assert np.isinf(cov[2, 2]) and not target.details["height_observable"]
    assert target.position[2] == 0.0  # held on the search plane, and said so
    assert HEIGHT_WARNING.split(":")[0] in target.details["warnings"][0]


def test_extended_target_centre_where_the_argmax_is_far_off():
    filtered, noisy = frame((4.0, 2.0, 0.0), size=(0.8, 1.2))
    paper = nl.locate(filtered, GRID, estimator="paper")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = nl.locate(filtered, GRID, estimator="model", raw=noisy)
    assert paper.error_m > 0.5  # the paper's argmax lands on the near edge
    assert model.error_m < 0.10


def test_non_collinear_spots_measure_height():
    truth = (3.0, 2.0, 0.3)
    filtered, noisy = frame(truth, spots=TRIANGLE)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no height warning here
        loc = nl.locate(filtered, GRID, estimator="model", raw=noisy)
    target = loc.targets[0]
    assert target.details["height_observable"]
    assert abs(target.position[2] - truth[2]) < 0.10 and loc.error_m < 0.10
    assert np.all(np.isfinite(target.covariance))


def test_two_targets_on_an_eight_spot_layout():
    truths = [(4.0, 2.0, 0.0), (2.0, 4.0, 0.0)]
    setup = nl.paper_setup(detector_spots=CIRCLE8)
    hists = [nl.simulate(nl.Scene(setup, nl.Target(nl.rectangle(0.3, 0.3, centre=t)), truth=t))
             .histograms() for t in truths]
    total = nl.upload(hists[0].with_data(hists[0].data + hists[1].data))
    noisy = nl.add_noise(total, 10, seed=1)
    loc = nl.locate(nl.gauss_filter(noisy), GRID, log_mode=True,
                    estimator=ModelEstimator(targets=2), raw=noisy)
    assert len(loc.targets) == 2
    for t in truths:
        assert min(np.linalg.norm(tg.position - t) for tg in loc.targets) < 0.10


def test_photon_counts_use_the_poisson_likelihood():
    signals = nl.simulate(nl.paper_scene()).histograms()
    counter = nl.PhotonCounter(n_pulses=80e6 * 3000 / 44234)  # ~3000 signal photons/detector
    counts = counter.counts(signals, seed=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loc = nl.locate(nl.gauss_filter(counts), GRID, estimator="model", raw=counts)
    assert loc.targets[0].details["likelihood"] == "poisson"
    assert loc.error_m < 0.10


def test_plate_facets_and_observability():
    f = plate_facets([4.0, 2.0, 0.0, 0.3, 1.6, math.pi], (10, 20))
    assert f.count == 200 and math.isclose(f.areas.sum(), 0.48)
    assert np.allclose(f.centres.mean(axis=0), [4.0, 2.0, 0.0])
    assert np.allclose(f.normals, [-1, 0, 0])
    assert not height_observable(nl.paper_setup().detector_spots, np.zeros(3))
    assert height_observable(np.array(TRIANGLE), np.zeros(3))


def test_choosing_the_model_estimator_by_name_loads_scipy_only_then():
    code = ("import sys, nlos_cl.localization.estimators as e; assert 'scipy' not in sys.modules; "
            "m = e.as_estimator('model'); print(m.name)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "model"


def test_the_default_estimator_is_the_model_fit_loaded_on_first_use():
    code = ("import sys, nlos_cl.localization.estimators as e; assert 'nlos_cl.localization.model' not in sys.modules; "
            "m = e.as_estimator(None); assert 'nlos_cl.localization.model' in sys.modules; print(m.name)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "model"
    filtered, noisy = frame((4.0, 2.0, 0.0))
    with pytest.warns(UserWarning, match="height"):
        loc = nl.locate(filtered, GRID, raw=noisy)  # no estimator: the default
    assert loc.estimator == "model" and loc.targets[0].details["model"] == "upright plate"
    assert loc.error_m < 0.02  # as test_paper_scene_centre_size_and_covariance


def test_box_model_is_the_plate_at_depth_zero():
    from nlos_cl.localization.model.shapes import box, plate
    spots, laser = np.array(TRIANGLE), np.zeros(3)
    p = np.array([3.0, 2.0, 0.3, 0.7, 1.1, 2.8])
    a = plate.model_facets(p, (16, 24), spots, laser)
    front, *sides = box.model_facets(box.from_plate(p, 0.0), (16, 24), spots, laser)
    assert all(np.all(s[0].areas == 0) for s in sides)  # a depth-0 box's sides have no area
    assert np.allclose(front[0].centres, a[0].centres) and math.isclose(a[1], front[1])
    assert np.allclose(a[2], front[2], atol=1e-15)
    deep = box.box_facets(box.from_plate(p, 0.4), (16, 24))  # all six faces, none culled
    assert math.isclose(deep.areas.sum(), 2 * (0.7 * 1.1 + 0.4 * 1.1 + 0.7 * 0.4))
    assert np.allclose(deep.centres.mean(axis=0), box.from_plate(p, 0.4)[:3], atol=1e-9)


def test_curved_shapes_cover_their_surface_and_cull_what_no_spot_sees():
    from nlos_cl.localization.model.shapes import cylinder, ellipsoid
    # The cell areas sum to the surface's: a sphere's 4 pi r^2 within the midpoint rule's
    # error (measured 0.16 % on 32 x 16 cells); a cylinder's side and caps exactly (flat in
    # height, the caps' rings summed exactly by the midpoint rule in radius).
    sphere = ellipsoid.ellipsoid_facets([2.0, 3.0, 0.0, 0.6, 0.6, 0.6, 1.0])
    assert math.isclose(sphere.areas.sum(), 4 * math.pi * 0.09, rel_tol=5e-3)
    # each cell's facet at its patch's mean position: inside the surface by the chord factors
    k_az, k_po = (ellipsoid.chord_mean(2 * math.pi / ellipsoid.CELLS[0]),
                  ellipsoid.chord_mean(math.pi / ellipsoid.CELLS[1]))
    radii = np.linalg.norm(sphere.centres - [2, 3, 0], axis=1)
    assert np.all(radii >= 0.3 * k_po * k_az - 1e-12) and np.all(radii <= 0.3 * k_po + 1e-12)
    can = cylinder.cylinder_facets([2.0, 3.0, 0.1, 0.4, 1.7, 0.4, 1.0])
    assert math.isclose(can.areas.sum(), 2 * math.pi * 0.2 * 1.7 + 2 * math.pi * 0.04,
                        rel_tol=1e-9)
    seen, _ = ellipsoid.ellipsoid_cells([2.0, 3.0, 0.0, 0.6, 0.6, 0.6, 1.0], np.array(TRIANGLE),
                                        np.zeros(3))
    assert 0 < seen.count < sphere.count  # the far side is dropped
    assert np.all(np.einsum("fk,fk->f", seen.normals, -seen.centres) > 0)  # faces the laser


def test_an_ambient_offset_under_the_signal_does_not_move_the_fit():
    """A constant level under every row (ambient light, dark counts: 2 % of each row's peak)
    is measured outside the signal and taken off (model.data.row_floors). Left in the fit's
    window, it was explained as a 0.76 m deep box 0.38 m off the plate (1 % of the peak)."""
    truth = (3.0, 2.0, 0.3)
    setup = nl.paper_setup(detector_spots=TRIANGLE)
    mesh = nl.rectangle(0.3, 1.6, centre=truth, normal=(-1, 0, 0))
    clean = nl.simulate(nl.Scene(setup, nl.Target(mesh), truth=truth)).histograms()
    noisy = nl.add_noise(clean, 20, seed=1).histograms()
    offset = noisy.with_data(noisy.data + 0.02 * clean.data.max(axis=1, keepdims=True))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loc = nl.locate(nl.gauss_filter(offset), GRID, estimator="model", raw=offset)
    assert loc.error_m < 0.01
    assert loc.targets[0].extent_m[2] == 0.0  # a plate, not a box


def test_row_floors_measure_the_level_outside_the_signal_only():
    from nlos_cl.localization.model.forward.data import MIN_FLOOR_BINS, row_floors
    rng = np.random.default_rng(0)
    rows = 0.5 + 0.01 * rng.standard_normal((2, 4000))
    rows[:, 1000:3500] += 10.0  # a signal over most of the record: a plain median says 10.5
    floors = row_floors(rows, np.array([[1000, 3499], [1000, 3499]]), np.full(2, 0.01))
    assert np.allclose(floors, 0.5, atol=0.01)
    short = row_floors(rows[:, :MIN_FLOOR_BINS + 10], np.array([[5, MIN_FLOOR_BINS + 5]] * 2),
                       np.full(2, 0.01))
    assert np.all(short == 0.0)  # too few bins outside: the level is unknown, nothing taken
    noise_only = 0.01 * rng.standard_normal((200, 4000))  # zero-mean: a level is noise's
    assert np.count_nonzero(row_floors(noise_only, np.array([[1000, 3499]] * 200),
                                       np.full(200, 0.01))) == 0
