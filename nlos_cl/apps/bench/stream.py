"""Frame-stream rows for `nlos-cl bench`: host frames (3 x 4,096 bins, 10 dB) on a 512^2 grid,
per frame, timed interleaved in one run (each repeat runs every case once, in turn):

- functional: nl.gauss_filter + nl.locate per frame (each builds its plan);
- plans: GaussFilter + Locator built once;
- tracker: nlos_cl.tracking.Tracker.update from the host frame to track states (upload,
  filter, locate, Kalman), with the paper's estimator and with the model-based one (targets:
  >= 500 and >= 100 frames/s, the model tracker's on the paper's scene, warm); the model
  tracker warm-starts each frame's fit from its confirmed track (nlos_cl.tracking.warm), and a
  second row, warm_start=False, fits every frame from its data alone (the rate before warm
  starts, measured in the same run).

The model trackers run fewer frames per repeat; their twin column is empty. One more row,
`crossing_row`: two targets crossing (crossing draw 1 of `reproduce draws`: 8 spots, a 3-D
region), tracked once as `nlos-cl track --targets 2` tracks it; its frames are a sequence, so
not repeated: the median over its frames after the first (target: >= 20 frames/s).
And `cold_row`: one frame located in-process from its data alone, against the paper's argmax
on the same frames (target: <= 20 ms and <= 15x the argmax).
"""
from __future__ import annotations

import math
import statistics
import time

import numpy as np

import nlos_cl as nl

from ...ops.backend import NumpyBackend
from ...simulation.stream import stream_frames


def _cases(rt, clean, frames, grid, smoke):
    """{label: (step(i), frames per repeat, twin step or None)}."""
    from ...localization.filter import GaussFilter
    from ...localization.locator import Locator
    from ...ops.signals import upload
    from ...tracking import Tracker
    from ...tracking.options import SearchPlan
    n = 20 if smoke else 200
    gauss, locator = GaussFilter(time_axis=clean.time_axis), Locator(clean.layout, grid, estimator="paper")
    paper = Tracker(clean.layout, grid, estimator="paper", backend=rt)
    model = Tracker(clean.layout, grid, estimator="model", backend=rt)
    cold = Tracker(clean.layout, grid, estimator="model", backend=rt,
                   plan=SearchPlan(warm_start=False))
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
        # the same fits with the plates on the device (ops/plate_model.py)
        "tracker, model estimator, model_on='kernel'": (lambda i: kernel.update(frames[i % k]),
                                                        4 if smoke else 40, None),
        "tracker, model estimator, warm_start=False": (lambda i: cold.update(frames[i % k]),
                                                       2 if smoke else 10, None),
    }


def _grid(smoke):
    """(the rows' search grid: a 4 m square of 512^2 cells, 64^2 smoke; its side in cells)."""
    from ...core.grid import Grid
    size = 64 if smoke else 512
    return Grid((2.0, 0.5, 0.0), (4 / size, 4 / size, 0.01), (size, size, 1)), size


def stream_rows(rt, smoke, Row):
    grid, size = _grid(smoke)
    clean, frames = stream_frames(rt)
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
        # measurements only: a check against a target belongs in the session note
        note = "per frame" + ("; twin: one frame" if twin is not None else "")
        rows.append(Row("stream", f"{label}: {n} frames x {repeats} repeats, 3 x 4096 bins, "
                        f"{size}x{size} cells", n, med, twin_s, 0.0, 1 / med, "frames",
                        math.nan, "-", 0.0, (max(times[label]) - min(times[label])) / med,
                        note=note))
    return rows


def cold_row(rt, smoke, Row):
    """One frame located from its data alone, in-process (`nl.locate(filtered, grid,
    raw=frame)`: the default model estimator, its plan cached), against the paper's argmax
    (`estimator="paper"`) on the same frames, interleaved frame by frame: the stream's 8 noise
    draws x 5 repeats, the median frame. The median, not the mean: one draw of the 8 (noise
    seed 0, copy 2) has the depth probe send the fit on to the closed shapes (~2-3 s; the
    warm_start=False tracker row's mean is mostly that frame), which the note counts."""
    grid, size = _grid(smoke)
    _, frames = stream_frames(rt)
    frames = frames[:2] if smoke else frames
    pairs = [(f, nl.gauss_filter(f, backend=rt)) for f in frames]
    for f, g in pairs[:2]:  # warm-up: programs and plans
        nl.locate(g, grid, raw=f)
        nl.locate(g, grid, estimator="paper")
    model, paper, closed = [], [], set()
    for _ in range(2 if smoke else 5):
        for k, (f, g) in enumerate(pairs):
            start = time.perf_counter()
            found = nl.locate(g, grid, raw=f)
            model.append(time.perf_counter() - start)
            start = time.perf_counter()
            nl.locate(g, grid, estimator="paper")
            paper.append(time.perf_counter() - start)
            if any((t.details or {}).get("closed_tried") for t in found.targets):
                closed.add(k)
    med, med_paper = statistics.median(model), statistics.median(paper)
    q1, q3 = np.percentile(model, [25, 75])
    return Row("stream", f"model estimate, cold (nl.locate, default estimator): {len(pairs)} "
               f"frames x {len(model) // len(pairs)} repeats, 3 x 4096 bins, {size}x{size} "
               "cells", len(model), med, math.nan, 0.0, 1 / med, "frames", math.nan, "-", 0.0,
               (q3 - q1) / med,
               note=f"median frame; spread: IQR / median; the paper's argmax on the same "
               f"frames {1e3 * med_paper:.2f} ms ({med / med_paper:.0f}x); frames whose fit "
               f"tried the closed shapes: {len(closed)} of {len(pairs)}")


CROSSING_DRAW = 1  # of `reproduce draws --only crossings` (master seed 2201): ids and RMS met


def crossing_row(rt, smoke, Row):
    """Two plates crossing on an 8-spot circle, tracked by nl.track_sequence's tracker (the model
    estimator, targets=2, warm starts, the gated search): per-frame Tracker.update times after
    the first frame; smoke: the first 8 frames."""
    import tempfile
    from pathlib import Path
    from ...simulation.draws import families
    from ..reproduce.draws import cross_run
    d = families.draw("crossings", CROSSING_DRAW, None)
    if smoke:
        d["frames"]["frames"] = 8
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "crossing.h5"
        cross_run.write_frames(d, path)
        out = cross_run.track_file(path)
    times = out["update_s"][1:]
    med = statistics.median(times)
    q1, q3 = np.percentile(times, [25, 75])
    return Row("stream", f"tracker, two targets crossing (crossing draw {CROSSING_DRAW}: 8 spots, "
               f"{len(times) + 1} frames, a 3-D region)", len(times), med, math.nan,
               out["setup_s"], 1 / med, "frames", math.nan, "-", 0.0, (q3 - q1) / med,
               note="median frame after the first; spread: IQR / median")
