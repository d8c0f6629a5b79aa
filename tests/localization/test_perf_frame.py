"""What one frame costs in launches and host round trips (counted, never timed): with the paper's
estimator a located frame is a handful of launches and ONE blocking read, coarse to fine and
exhaustive alike (nlos_cl/ops/fused_search.py, argmax_patch.py); the Tracker adds only the
frame's upload and the Gauss filter."""
import numpy as np
import pyopencl as cl
import pytest
from test_search import histograms

import nlos_cl as nl
from nlos_cl.localization.filter import GaussFilter
from nlos_cl.localization.locator import Locator
from nlos_cl.tracking import Tracker
from nlos_cl.tracking.options import SearchPlan


class Counter:
    def __init__(self, monkeypatch):
        self.launches = self.reads = self.writes = 0
        self.written = []  # bytes of each write
        launch, copy = cl.enqueue_nd_range_kernel, cl.enqueue_copy

        def counted_launch(*args, **kw):
            self.launches += 1
            return launch(*args, **kw)

        def counted_copy(queue, dest, src, **kw):
            if isinstance(dest, np.ndarray):
                self.reads += 1
            else:
                self.writes += 1
                self.written.append(getattr(src, "nbytes", -1))
            return copy(queue, dest, src, **kw)
        monkeypatch.setattr(cl, "enqueue_nd_range_kernel", counted_launch)
        monkeypatch.setattr(cl, "enqueue_copy", counted_copy)


# coarse to fine: row stats + dilation, the coarse pair, then the candidates, the refinement
# over every work group and its finish (three launches, so the refinement is not one group's)
@pytest.mark.parametrize("search, launches", [("coarse_to_fine", 5), ("exhaustive", 4)])
def test_a_located_frame_is_one_read(runtime, monkeypatch, search, launches):
    hist = histograms([(4.0, 2.0, 0.0)], [1.0], 3, 0.065, 0.05, 6)
    grid = nl.Grid.from_ranges(x=(2.0, 6.0), y=(0.5, 4.0), step_m=0.01)
    signals = GaussFilter(time_axis=hist.time_axis)(nl.upload(hist, runtime))
    plan = Locator(hist.layout, grid, search=search, backend=runtime, estimator="paper")
    plan(signals)  # builds the programs, allocates the plan's buffers
    runtime.finish()
    count = Counter(monkeypatch)
    plan(signals, detect=False)
    assert (count.launches, count.reads, count.writes) == (launches, 1, 0)
    count = Counter(monkeypatch)
    plan(signals)  # detection before location reads the filtered rows: one more read
    assert (count.launches, count.reads, count.writes) == (launches, 2, 0)


@pytest.mark.parametrize("gated", [False, True])
def test_a_tracked_frame_is_one_upload_and_one_read(runtime, monkeypatch, gated):
    # inside the 9 m record (the (4, 2) target's peak lies beyond it: too faint to detect)
    hist = histograms([(3.0, 1.5, 0.0)], [1.0], 3, 0.065, 0.05, 7)
    grid = nl.Grid.from_ranges(x=(2.0, 6.0), y=(0.5, 4.0), step_m=0.01)
    tracker = Tracker(hist.layout, grid, backend=runtime,
                      plan=SearchPlan(search="coarse_to_fine", gated_search=gated))
    for _ in range(3):  # until the track is confirmed: detection (gating births) then stops
        tracker.update(hist)
    assert [t.status for t in tracker.tracks] == ["confirmed"]
    count = Counter(monkeypatch)
    tracker.update(hist)
    windowed = tracker.locator.windows.last is not None
    assert windowed == gated  # this frame's gate box is smaller than what the search scores
    # the frame; a windowed frame also its tile's first cell (one int4, 16 bytes: uploaded
    # once per content, so not again while the window stays where it was)
    assert count.reads == 1 and [n for n in count.written if n > 16] == [hist.data.nbytes // 2]
    assert count.writes <= 1 + windowed
    assert count.launches <= 8  # Gauss filter (2), row stats + dilation, coarse, refinement (3)
