"""Paired and confocal layouts (each histogram its own laser spot): built from nlos_cl's own
one-laser simulations (each histogram simulated with its own laser spot, so the forward model,
not the scoring kernel, puts the signal at |c - L_i| + |c - D_i|), located with the paper's
estimator. Physics checks neither implementation can fake: the located point is the target's
front; reciprocity (N lasers + one detector is one laser + N detectors, swapped) gives the
same map; a layout with one laser for all equals its paired form with that laser repeated."""
import warnings

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.core.errors import InputError
from nlos_cl.localization.estimate import Capabilities
from nlos_cl.tracking.options import SearchPlan

TARGET = (3.0, 2.0, 0.0)
AXIS = nl.default_time_axis(nl.paper_setup(), 1e-11, max_hidden_path_m=9.0)  # every leg here


def _one(laser, detector, runtime):
    """One histogram: laser -> target -> detector, simulated by the forward model."""
    mesh = nl.rectangle(0.3, 0.6, centre=TARGET, normal=(-1.0, -1.0, 0.0), cell_m=0.02)
    setup = nl.paper_setup(laser_spot=laser, detector_spots=[detector])
    sig = nl.simulate(nl.Scene(setup, nl.Target(mesh), 0.02, truth=TARGET), AXIS,
                      backend=runtime)
    h = sig.histograms()
    return h.data[0], h.calibration.offsets(1)[0], h.calibration.a_m_per_s


def _paired(lasers, detectors, runtime) -> nl.HistogramSet:
    rows = [_one(lz, d, runtime) for lz, d in zip(lasers, detectors)]
    data = np.array([r[0] for r in rows])
    cal = nl.PathCalibration(rows[0][2], np.array([r[1] for r in rows]))
    return nl.HistogramSet(data, AXIS, np.asarray(detectors, float), np.asarray(lasers, float),
                           cal, truth=TARGET)


SCAN = [(x, 0.0, z) for x in (-0.6, -0.2, 0.2, 0.6) for z in (-0.3, 0.3)]
GRID = nl.Grid.from_ranges(x=(2.0, 4.0), y=(1.0, 3.0), z=(-0.4, 0.4), step_m=0.02)


def _front_distance(position) -> float:
    """Distance from the plate's plane (normal (-1, -1, 0)/sqrt 2 through TARGET)."""
    n = np.array([-1.0, -1.0, 0.0]) / np.sqrt(2)
    return float(abs((np.asarray(position) - TARGET) @ n))


def test_confocal_scan_is_located_on_the_target(runtime):
    """Laser and detection point 1 mm apart (the forward model's setup refuses one spot for
    both), labelled confocal: the located point lies on the plate (its front face, within two
    cells of its plane) and within its half-width of the centre."""
    near = [(x + 1e-3, y, z) for x, y, z in SCAN]
    h = _paired(SCAN, near, runtime)
    h = nl.HistogramSet(h.data, AXIS, np.asarray(SCAN, float), np.asarray(SCAN, float),
                        h.calibration, truth=TARGET)
    assert h.paired
    loc = nl.locate(nl.gauss_filter(h), GRID, estimator="paper", log_mode=True)
    assert _front_distance(loc.position) < 0.04
    assert np.linalg.norm(loc.position - TARGET) < 0.35


def test_reciprocity_n_lasers_one_detector_is_one_laser_n_detectors(runtime):
    """Swapping laser and detector leaves every path, so the score maps are the same."""
    d = (-1.0, 0.0, 0.1)
    h = _paired(SCAN, [d] * len(SCAN), runtime)
    swapped = nl.HistogramSet(h.data, AXIS, np.asarray(SCAN, float), np.asarray(d, float),
                              h.calibration, truth=TARGET)
    a = nl.locate(nl.gauss_filter(h), GRID, estimator="paper", return_map=True, log_mode=True)
    b = nl.locate(nl.gauss_filter(swapped), GRID, estimator="paper", return_map=True,
                  log_mode=True)
    assert np.allclose(a.score_map, b.score_map, rtol=0, atol=1e-4)  # float32, log units
    assert np.allclose(a.position, b.position, atol=1e-6)
    assert _front_distance(a.position) < 0.04


def test_one_laser_written_as_paired_gives_the_same_answer(runtime):
    scene = nl.paper_scene(facet_size_m=0.03)
    clean = nl.simulate(scene, nl.default_time_axis(scene.setup, 1e-11), backend=runtime)
    h = nl.add_noise(clean, 10.0, seed=1).histograms()
    paired = nl.HistogramSet(h.data, h.time_axis, h.detector_spots,
                             np.tile(h.laser_spot, (h.n_detectors, 1)), h.calibration)
    grid = nl.Grid.from_ranges(x=(3.0, 5.0), y=(1.0, 3.0), step_m=0.01)
    for search in ("exhaustive", "coarse_to_fine"):
        a = nl.locate(nl.gauss_filter(h), grid, estimator="paper", search=search)
        b = nl.locate(nl.gauss_filter(paired), grid, estimator="paper", search=search)
        assert np.array_equal(a.position, b.position) and a.score == b.score


def test_the_model_estimator_fits_a_paired_layout(runtime):
    """N lasers + one detector at 20 dB: the plate fit (the forward op with a laser per
    detector) finds the centre within 1 cm and the 0.3 x 0.6 m size within 2 cm."""
    h = _paired(SCAN, [(-1.0, 0.0, 0.1)] * len(SCAN), runtime)
    noisy = nl.add_noise(nl.upload(h, runtime), 20.0, seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loc = nl.locate(nl.gauss_filter(noisy), GRID, estimator="model", raw=noisy,
                        log_mode=True)
    fit = loc.targets[0].fit
    assert np.linalg.norm(loc.position - TARGET) < 0.01
    assert fit.shape == "plate" and abs(fit["width"].value - 0.3) < 0.02
    assert abs(fit["height"].value - 0.6) < 0.02


def test_paired_captures_default_to_the_papers_argmax_and_say_so(runtime):
    d = (-1.0, 0.0, 0.1)
    h = _paired(SCAN[:3], [d] * 3, runtime)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        point = nl.locate_capture(h, region=GRID).points[0]
    assert point.location.estimator == "paper"
    assert any("located with the paper's argmax by default" in w for w in point.warnings)
    # the library's default answer carries the paper likelihood's spread as its uncertainty
    # (it had none), whose trace is a few cells' squared width, not zero or unbounded
    cov = point.covariances[0]
    assert cov is not None and np.all(np.isfinite(np.diag(cov))) and np.all(np.diag(cov) > 0)
    assert np.trace(cov) < 1.0
    paper = nl.locate_capture(h, region=GRID, estimator="paper").points[0]
    np.testing.assert_array_equal(paper.position, point.position)
    assert paper.covariances[0] is not None


class _OneLaserOnly(nl.PaperArgmax):
    capabilities = Capabilities(local=True)  # paired=False: says it cannot


def test_an_estimator_without_pairing_is_refused_or_replaced(runtime):
    h = _paired(SCAN[:3], [(-1.0, 0.0, 0.1)] * 3, runtime)
    with pytest.raises(InputError, match="fits layouts with one laser"):
        nl.Locator(h, GRID, estimator=_OneLaserOnly())
    point = nl.locate_capture(h, region=GRID, estimator=_OneLaserOnly()).points[0]
    assert any("located with the paper's argmax" in w for w in point.warnings)


def test_a_laser_per_histogram_must_match_the_histograms():
    with pytest.raises(InputError, match="histograms.laser_spot"):
        nl.HistogramSet(np.zeros((3, AXIS.n_bins)), AXIS, np.zeros((3, 3)), np.zeros((2, 3)),
                        nl.PathCalibration(3e8, 0.0))


def test_the_tracker_follows_a_target_in_a_paired_layout(runtime):
    """N lasers + one detector, three noisy frames of a still target: one confirmed track."""
    from nlos_cl.tracking import Tracker
    h = _paired(SCAN, [(-1.0, 0.0, 0.1)] * len(SCAN), runtime)
    tracker = Tracker(h, GRID, estimator="paper", plan=SearchPlan(log_mode=True))
    for k in range(3):
        tracks = tracker.update(nl.add_noise(nl.upload(h, runtime), 20.0, seed=k), 0.1 * k)
    assert len(tracks) == 1 and tracks[0].status == "confirmed"
    assert _front_distance(tracks[0].position) < 0.05
