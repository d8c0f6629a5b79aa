"""Frame-stream rows for `nlos-cl bench`: host frames (3 x 4,096 bins, 10 dB) on a 512^2 grid,
per frame, timed interleaved in one run (each repeat runs every case once, in turn):

- functional: nl.gauss_filter + nl.locate per frame (each builds its plan);
- plans: GaussFilter + Locator built once;
- tracker: nlos_cl.tracking.Tracker.update from the host frame to track states (upload,
  filter, locate, Kalman), with the paper's estimator and with the model-based one (issue 12's
  goals: >= 500 and >= 30 frames/s; issue 23 raised the model tracker's to 100); the model
  tracker warm-starts each frame's fit from its confirmed track (nlos_cl.tracking.warm), and a
  second row, warm_start=False, fits every frame from its data alone (the rate before warm starts, measured in the same run).

The model trackers run fewer frames per repeat; their twin column is empty. One more row,
`crossing_row`: two targets crossing (crossing draw 1 of `reproduce draws`: 8 spots, a 3-D
region), tracked once as `nlos-cl track --targets 2` tracks it; its frames are a sequence, so
not repeated: the median over its frames after the first (issue 23's goal: >= 20 frames/s).
"""
from __future__ import annotations

import math
import statistics
import time

import numpy as np

import nlos_cl as nl

from ...ops.backend import NumpyBackend

# frames/s: issue 12's (500 and 30), the model tracker's raised by issue 23 (warm, paper's scene)
GOALS = {"tracker, paper estimator": 500.0, "tracker, model estimator": 100.0}


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
    from ...localization.model import ModelEstimator
    kernel = Tracker(clean.layout, grid, estimator=ModelEstimator(model_on="kernel"), backend=rt)
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
        # the same fits with the plates on the device (ops/plate_model.py): issue 23 item 1
        "tracker, model estimator, model_on='kernel'": (lambda i: kernel.update(frames[i % k]),
                                                        4 if smoke else 40, None),
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


CROSSING_DRAW = 1  # of `reproduce draws --only crossings` (master seed 2201): ids and RMS met


def crossing_row(rt, smoke, Row):
    """Two plates crossing on an 8-spot circle, tracked by make_tracker's tracker (the model
    estimator, targets=2, warm starts, the gated search): per-frame Tracker.update times after
    the first frame; smoke: the first 8 frames."""
    import tempfile
    from pathlib import Path
    from ..reproduce import draws_cross_run, draws_gen
    d = draws_gen.draw("crossings", CROSSING_DRAW, None)
    if smoke:
        d["frames"]["frames"] = 8
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "crossing.h5"
        draws_cross_run.write_frames(d, path)
        out = draws_cross_run.track_file(path)
    times = out["update_s"][1:]
    med = statistics.median(times)
    q1, q3 = np.percentile(times, [25, 75])
    return Row("stream", f"tracker, two targets crossing (crossing draw {CROSSING_DRAW}: 8 spots, "
               f"{len(times) + 1} frames, a 3-D region)", len(times), med, math.nan,
               out["setup_s"], 1 / med, "frames", math.nan, "-", 0.0, (q3 - q1) / med,
               note="median frame after the first; spread: IQR / median; goal (issue 23) "
               f">= 20 frames/s: {'met' if 1 / med >= 20 else 'NOT met'}")
