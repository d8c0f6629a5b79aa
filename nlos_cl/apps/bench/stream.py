"""Frame-stream rows for `nlos-cl bench`: host frames (3 x 4,096 bins, 10 dB) on a 512^2 grid,
per frame, timed interleaved in one run (each repeat runs every case once, in turn):

- functional: nl.gauss_filter + nl.locate per frame (each builds its plan);
- plans: GaussFilter + Locator built once;
- tracker: nlos_cl.tracking.Tracker.update from the host frame to track states (upload,
  filter, locate, Kalman), with the paper's estimator and with the model-based one (issue 12's
  goals: >= 500 and >= 30 frames/s); the model tracker warm-starts each frame's fit from its
  confirmed track (nlos_cl.tracking.warm), and a second row, warm_start=False, fits every frame
  from its data alone (the rate before warm starts, measured in the same run).

The model trackers run fewer frames per repeat; their twin column is empty.
"""
from __future__ import annotations

import math
import statistics
import time

import numpy as np

import nlos_cl as nl

from ...ops.backend import NumpyBackend

GOALS = {"tracker, paper estimator": 500.0, "tracker, model estimator": 30.0}  # frames/s


def _frames(rt, n_copies=8):
    from ...core.paths import TimeAxis
    from ...physics.scene import paper_scene
    clean = nl.simulate(paper_scene(facet_size_m=0.02), TimeAxis(40 / 299_792_458.0, 10e-12, 4096),
                        backend=rt).histograms()
    rng = np.random.default_rng(0)
    power = np.sqrt(np.mean(clean.data ** 2, axis=1, keepdims=True) / 10.0)
    # cycled: the noise draws are not what is timed
    return clean, [clean.with_data(clean.data + power * rng.standard_normal(clean.data.shape))
                   for _ in range(n_copies)]


def _cases(rt, clean, frames, grid, smoke):
    """{label: (step(i), frames per repeat, twin step or None)}."""
    from ...localization.filter import GaussFilter
    from ...localization.locator import Locator
    from ...ops.signals import upload
    from ...tracking import Tracker
    n = 20 if smoke else 200
    gauss, locator = GaussFilter(time_axis=clean.time_axis), Locator(clean.layout, grid, estimator="paper")
    paper = Tracker(clean.layout, grid, estimator="paper", backend=rt)
    model = Tracker(clean.layout, grid, estimator="model", backend=rt)
    cold = Tracker(clean.layout, grid, estimator="model", backend=rt, warm_start=False)
    k = len(frames)

    def twin_tracker(estimator):
        tracker = Tracker(clean.layout, grid, estimator=estimator, backend=NumpyBackend())
        return lambda i: tracker.update(frames[i % k])
    return {
        "functional: nl.gauss_filter + nl.locate per frame": (
            lambda i: nl.locate(nl.gauss_filter(frames[i % k], backend=rt), grid,
                                estimator="paper"), n,
            lambda i: nl.locate(nl.gauss_filter(frames[i % k], backend=NumpyBackend()), grid,
                             estimator="paper")),
        "plans: GaussFilter + Locator built once": (
            lambda i: locator(gauss(upload(frames[i % k], rt))), n, None),
        "tracker, paper estimator": (lambda i: paper.update(frames[i % k]), n,
                                     twin_tracker("paper")),
        "tracker, model estimator": (lambda i: model.update(frames[i % k]), 4 if smoke else 40,
                                     None),
        "tracker, model estimator, warm_start=False": (lambda i: cold.update(frames[i % k]),
                                                       2 if smoke else 10, None),
    }


def stream_rows(rt, smoke, Row):
    from ...core.grid import Grid
    size = 64 if smoke else 512
    grid = Grid((2.0, 0.5, 0.0), (4 / size, 4 / size, 0.01), (size, size, 1))
    clean, frames = _frames(rt)
    cases = _cases(rt, clean, frames, grid, smoke)
    for step, _, _ in cases.values():  # warm-up: programs, and "auto" searches' trials
        for i in range(10):
            step(i)
    rt.finish()
    times, repeats = {label: [] for label in cases}, 3 if smoke else 5
    for _ in range(repeats):  # interleaved repeats
        for label, (step, n, _) in cases.items():
            start = time.perf_counter()
            for i in range(n):
                step(i)
            rt.finish()
            times[label].append((time.perf_counter() - start) / n)
    rows = []
    for label, (_, n, twin) in cases.items():
        med = statistics.median(times[label])
        twin_s = math.nan
        if twin is not None:
            twin(0)
            start = time.perf_counter()
            twin(1)
            twin_s = time.perf_counter() - start
        goal = GOALS.get(label)
        note = "per frame; twin: one frame" + (
            f"; goal >= {goal:.0f} frames/s: {'met' if 1 / med >= goal else 'NOT met'}"
            if goal else "")
        rows.append(Row("stream", f"{label}: {n} frames x {repeats} repeats, 3 x 4096 bins, "
                        f"{size}x{size} cells", n, med, twin_s, 0.0, 1 / med, "frames",
                        math.nan, "-", 0.0, (max(times[label]) - min(times[label])) / med,
                        note=note))
    return rows
