"""The gated search: the paper's argmax searched in a window of the region (Locator(within=...),
nlos_cl/localization/window.py) and the tracker's box around its gates (nlos_cl/tracking/gated.py).
A window holding the region's best cell gives that cell and its score bit for bit (the same
cells, scored by the same kernel); a window whose best cell lies on its inner face gives way to
the whole region; a tracker with the gated search tracks as the ungated one does."""
import numpy as np
import pytest
from test_search import histograms

import nlos_cl as nl
from nlos_cl.localization.locator import Locator
from nlos_cl.localization.window import on_inner_face, sub_grid
from nlos_cl.tracking import gated
from nlos_cl.tracking.options import MeasurementNoise, SearchPlan

VOLUME = nl.Grid((2.0, 0.5, -0.6), (0.03, 0.03, 0.03), (120, 110, 40))


def _frame(target=(3.4, 2.1, 0.1), seed=0):
    return histograms([target], [1.0], 6, 0.06, 0.05, seed)


@pytest.mark.parametrize("search, twin", [("exhaustive", False), ("coarse_to_fine", False),
                                          ("exhaustive", True)])
def test_a_window_holding_the_best_cell_gives_the_region_answer(runtime, search, twin):
    """On the device and on the float64 twins (NumpyBackend): the same cell, score, position."""
    from nlos_cl.ops.backend import NumpyBackend
    hist = _frame()
    plan = Locator(hist.layout, VOLUME, estimator="paper", search=search,
                   backend=NumpyBackend() if twin else runtime)
    whole = plan(hist)
    cell = whole.cell_position
    got = plan(hist, within=np.stack([cell - 0.3, cell + 0.4]))  # (2, 3) array, or 2 corners
    assert plan.windows.last is not None  # the window was searched, not the region
    assert plan.windows.last.n_cells < 0.05 * VOLUME.n_cells
    assert np.allclose(got.cell_position, cell, rtol=0, atol=1e-12)
    assert got.score == whole.score  # the same cell scored by the same kernel
    assert np.allclose(got.position, whole.position, rtol=0, atol=1e-9)


def test_a_window_whose_best_cell_is_on_its_inner_face_gives_way_to_the_region(runtime):
    hist = _frame()
    plan = Locator(hist.layout, VOLUME, estimator="paper", backend=runtime)
    whole = plan(hist)
    cell = whole.cell_position
    off = cell + np.array([0.9, 0.0, 0.0])  # a window beside the target, not holding it
    got = plan(hist, within=(off - 0.3, off + 0.3))
    assert plan.windows.last is None
    assert np.array_equal(got.cell_position, whole.cell_position) and got.score == whole.score


def test_windows_are_the_region_cells_inside_the_box():
    window, first = sub_grid(VOLUME, (2.5, 1.0, -0.2), (2.9, 1.3, 0.0), VOLUME.n_cells)
    cells = np.array(window.origin) - np.array(VOLUME.origin)
    assert np.allclose(cells, np.array(first) * VOLUME.step, rtol=0, atol=1e-12)
    lo = np.array(window.origin)
    hi = lo + np.array(window.step) * (np.array(window.shape) - 1)
    step = np.array(VOLUME.step)
    # every cell centre in the box, and the next cell on either side outside it
    assert np.all(lo >= [2.5 - 1e-9, 1.0 - 1e-9, -0.2 - 1e-9]) and np.all(lo - step < [2.5, 1.0, -0.2])
    assert np.all(hi <= [2.9 + 1e-9, 1.3 + 1e-9, 0.0 + 1e-9]) and np.all(hi + step > [2.9, 1.3, 0.0])
    assert sub_grid(VOLUME, (2.5, 1.0, -0.2), (2.9, 1.3, 0.0), window.n_cells - 1) is None
    assert sub_grid(VOLUME, (9, 9, 9), (10, 10, 10), VOLUME.n_cells) is None  # no cell at all
    # the region's own faces are no inner faces
    assert not on_inner_face((0, 3, 3), (0, 5, 5), window, VOLUME)
    assert on_inner_face((0, 3, 3), (4, 5, 5), window, VOLUME)


def test_a_bad_window_is_refused_naming_within(runtime):
    hist = _frame()
    plan = Locator(hist.layout, VOLUME, estimator="paper", backend=runtime)
    for bad in [((3, 2, 0), (2, 2, 0)), ((np.nan, 0, 0), (1, 1, 1)), (1, 2), "box"]:
        with pytest.raises(nl.InputError, match="within"):
            plan(hist, within=bad)


class _Track:
    def __init__(self, status="confirmed", misses=0, plate=None):
        self.status, self.misses, self.plate, self.dims = status, misses, plate, 3


class _Prediction:
    def __init__(self, track, x, sd):
        self.track, self.x, self.P = track, np.r_[x, 0, 0, 0], np.diag([sd ** 2] * 6)


def test_the_box_holds_every_gate_and_only_when_no_slot_is_open():
    a, b = _Track(), _Track(plate=np.array([0, 0, 0, 0.3, 1.6, 0]))
    preds = [_Prediction(a, [3.0, 2.0, 0.0], 0.02), _Prediction(b, [4.0, 1.0, 0.1], 0.02)]
    lo, hi = gated.box_of(preds, [a, b], 2, 0.999, 0.05, VOLUME)
    reach = np.sqrt(16.266) * np.hypot(0.02, 0.05)  # the 3-dof gate's radius at 0.999: 0.22
    half_a = max(reach, gated.MIN_HALF_M)  # 0.25
    half_b = half_a + 0.5 * np.hypot(0.3, 1.6)  # b's plate: its surface around its centre
    top = np.array(VOLUME.origin) + np.array(VOLUME.step) * (np.array(VOLUME.shape) - 1)
    want_lo = np.maximum(np.minimum([3.0 - half_a, 2.0 - half_a, -half_a],
                                    [4.0 - half_b, 1.0 - half_b, 0.1 - half_b]), VOLUME.origin)
    want_hi = np.minimum(np.maximum([3.0 + half_a, 2.0 + half_a, half_a],
                                    [4.0 + half_b, 1.0 + half_b, 0.1 + half_b]), top)
    np.testing.assert_allclose(lo, want_lo, atol=1e-9)
    np.testing.assert_allclose(hi, want_hi, atol=1e-9)
    # a free slot (births), a tentative track or one that missed: the whole region
    assert gated.box_of(preds[:1], [a], 2, 0.999, 0.05, VOLUME) is None
    assert gated.box_of(preds, [a, _Track(misses=1)], 2, 0.999, 0.05, VOLUME) is None
    assert gated.box_of(preds, [a, _Track("tentative")], 2, 0.999, 0.05, VOLUME) is None


def test_the_gated_tracker_tracks_as_the_ungated_one(runtime):
    """A plate walking 1.1 m past 3 spots on a volume region, the paper's estimator: every
    frame's measurement the same with and without the gated search, which is used once the
    track is confirmed."""
    from nlos_cl.tracking import MovingTarget, Tracker, Trajectory, simulate_sequence
    setup = nl.paper_setup()
    walk = Trajectory([0, 1.2], [[3, 1.5, 0], [3.5, 2.5, 0]])
    target = MovingTarget(nl.Target(nl.rectangle(0.3, 0.3, centre=walk.at(0), cell_m=0.03)),
                          walk)
    frames = list(simulate_sequence(setup, target, n_frames=12, fps=10, noise=nl.AWGN(10),
                                    seed=0, facet_size_m=0.03, backend=runtime,
                                    time_axis=nl.default_time_axis(setup, 1e-11)))
    grid = nl.Grid((2.0, 0.8, -0.6), (0.02, 0.02, 0.04), (120, 120, 31))
    measured, windows = {}, 0
    for gate in (False, True):
        tracker = Tracker(frames[0].signals, grid, backend=runtime, plan=SearchPlan(gated_search=gate),
                          noise=MeasurementNoise(fallback_sigma_m=0.02))
        measured[gate] = []
        for frame in frames:
            tracker.update(frame.signals, frame.t_s)
            measured[gate].append([m.position for m in tracker.last_measurements])
            windows += gate and tracker.locator.windows.last is not None
    assert windows >= 6
    for a, b in zip(measured[False], measured[True]):
        assert len(a) == len(b)
        assert all(np.allclose(p, q, rtol=0, atol=1e-9) for p, q in zip(a, b))
