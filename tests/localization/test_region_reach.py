"""The derived search region reaches only as far as the histograms' signal does
(localization.region.signal_reach): the target stays inside, an empty capture keeps the whole
window, and the answer is the same as on the whole window."""
import numpy as np

import nlos_cl as nl
from nlos_cl.localization.region import default_region, signal_reach, visible_box


def _capture(position=(2.0, 1.5, 0.0), snr_db=10.0):
    scene = nl.paper_scene(position=position)
    return nl.add_noise(nl.simulate(scene), snr_db, seed=0).histograms()


def _contains(grid, p):
    lo = np.array(grid.origin)
    hi = lo + np.array(grid.step) * (np.array(grid.shape) - 1)
    return bool(np.all(p[:2] >= lo[:2] - 1e-9) and np.all(p[:2] <= hi[:2] + 1e-9))


def test_the_region_ends_where_the_signal_does_and_holds_the_target():
    h = _capture()
    reach = signal_reach([h])
    whole = h.path_axis().stop_m
    assert reach is not None and np.all(reach < whole)
    truth = np.array([2.0, 1.5, 0.0])
    paths = np.linalg.norm(truth) + np.linalg.norm(truth - h.detector_spots, axis=1)
    assert np.all(reach > paths + 0.3)  # the target's paths, with the margin beyond
    grid, full = default_region(h), default_region(h, reach_from=())
    assert grid.n_cells < full.n_cells and _contains(grid, truth)
    lo, hi = visible_box(h, reach)
    assert hi[1] < visible_box(h)[1][1]


def test_no_signal_keeps_the_whole_window():
    h = _capture()
    empty = nl.HistogramSet(np.zeros_like(h.data), h.time_axis, h.detector_spots,
                            h.laser_spot, h.calibration)
    assert signal_reach([empty]) is None
    assert default_region(empty) == default_region(empty, reach_from=())


def test_the_answer_does_not_move():
    h = _capture()
    a = nl.locate_capture(h, estimator="paper").points[0].location.position
    whole = default_region(h, reach_from=())
    b = nl.locate_capture(h, estimator="paper", region=whole).points[0].location.position
    assert np.linalg.norm(a - b) < 0.02

