"""The benchmark's cases: every registered operation's "bench" examples (kernel against twin),
then the whole pipeline and a frame stream (functional calls, plans and the Tracker: stream.py).
"""
from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass, field

import numpy as np

import nlos_cl as nl

from ...ops import OPERATIONS
from ...ops.backend import NumpyBackend
from .harness import fraction_of_limit, measure_limits, spread, time_pair, timed


@dataclass
class Row:
    case: str
    size: str
    work: float  # problem size for the plot (work units, or frames)
    kernel_s: float  # median
    twin_s: float
    build_s: float
    throughput: float
    unit: str
    fraction: float  # of the limit named in `bound`, probed right before this case
    bound: str
    peak_host_mb: float
    spread: float = 0.0  # kernel (max - min) / median over the repeats
    limit_spread: float = 0.0  # the probe's own spread
    note: str = ""
    limits: dict = field(default_factory=dict)
    peers: dict = field(default_factory=dict)  # peer name -> seconds (median), same inputs

    @property
    def ratio(self) -> float:
        return self.twin_s / self.kernel_s


def operation_rows(rt, smoke, say):
    twin = NumpyBackend()
    for op in OPERATIONS.values():
        examples = op.examples("check")[:1] if smoke else op.examples("bench")
        for ex in examples:
            say(f"  {op.name}: {ex.label}")
            args = ex.inputs(rt)
            twin_args = (ex.twin_inputs or ex.inputs)(twin)
            kernel, twin_t, build, mem = time_pair(
                lambda: rt.call(op.name, *args), lambda: twin.call(op.name, *twin_args),
                rt.finish, twin_repeats=1 if ex.twin_inputs or ex.work > 1e9 else 3)
            k, k_spread = spread(kernel)
            limits = measure_limits(rt, smoke)  # next to the case it judges
            frac, probe = fraction_of_limit(limits, ex.work, ex.unit, k)
            note = (f"twin timed on {ex.twin_fraction:.0%} of the work, scaled"
                    if ex.twin_inputs else "")
            peers = filter_peers(twin_args) if op.name == "gauss_filter" else {}
            yield Row(op.name, ex.label, ex.work or 1.0, k,
                      statistics.median(twin_t) / ex.twin_fraction, build,
                      (ex.work or 1.0) / k, ex.unit or "calls", frac,
                      f"{op.bound}" + (f" (fraction: vs {probe} probe)" if probe else ""), mem,
                      k_spread, limits.get(_probe_key(probe) + "_spread", 0.0), note, limits,
                      peers)


def filter_peers(args, repeats=5) -> dict:
    """SciPy on the host, same float32 rows and taps: overlap-add and plain FFT convolution."""
    from scipy.signal import fftconvolve, oaconvolve
    data = np.asarray(args[0], np.float32)
    taps = np.asarray(args[1], np.float32)[None, ::-1]
    times = {"scipy oaconvolve": [], "scipy fftconvolve": []}
    for _ in range(repeats):  # interleaved
        for name, fn in (("scipy oaconvolve", oaconvolve), ("scipy fftconvolve", fftconvolve)):
            start = time.perf_counter()
            fn(data, taps, mode="same", axes=1)
            times[name].append(time.perf_counter() - start)
    return {k: statistics.median(v) for k, v in times.items()}


def _probe_key(probe):
    return {"exp": "exp_per_s", "FMA": "fma_per_s", "bandwidth": "bytes_per_s"}.get(probe, "")


def pipeline_row(rt, smoke):
    from ...core.grid import Grid
    from ...core.paths import TimeAxis, default_time_axis
    from ...physics.scene import paper_scene
    scene = paper_scene(facet_size_m=0.05 if smoke else 0.01)
    axis = TimeAxis(40 / 299_792_458.0 + 29e-9, 1e-12, 8_000) if smoke else default_time_axis(
        scene.setup)
    grid = Grid.from_ranges(x=(3, 5), y=(1, 3), step_m=0.05) if smoke else Grid()

    def run(backend):
        f = nl.gauss_filter(nl.add_noise(nl.simulate(scene, axis, backend=backend), 10.0, 0))
        return nl.locate(f, grid, estimator="paper")
    kernel, twin, build, mem = time_pair(lambda: run(rt), lambda: run(NumpyBackend()),
                                         rt.finish, twin_repeats=1)
    k, k_spread = spread(kernel)
    return Row("pipeline", "demo: simulate, noise, filter, locate", 1, k,
               statistics.median(twin), build, 1 / k, "localizations", math.nan, "-", mem,
               k_spread)


def closed_shapes_row(rt, smoke):
    """One Jacobian's columns (a row and its 7 steps) of each closed shape (box, ellipsoid,
    cylinder) on the paper's 3 spots: the forward op on the device, one launch per lit face and
    row (likelihood.Problem), against the host's batched float64 model (model.host_shapes),
    which model_on='auto' uses here: on such small problems launches and read-backs cost more
    than the arithmetic."""
    from ...localization.estimate import Scored
    from ...localization.model import ModelEstimator
    from ...localization.model.shapes import box, cylinder, ellipsoid
    from ...localization.model.forward.host_shapes import HostShapeProblem
    from ...localization.model.forward.likelihood import Problem
    from ...physics.scene import Scene, Target, paper_setup
    truth = (4.0, 2.0, 0.0)
    scene = Scene(paper_setup(), Target(nl.rectangle(0.3, 1.6, centre=truth)), truth=truth)
    raw = nl.add_noise(nl.simulate(scene, backend=rt), 10.0, seed=3)
    filtered = nl.gauss_filter(raw)
    obs = ModelEstimator().observation(Scored(filtered.backend, None, nl.Grid(), False,
                                              filtered.n_detectors, filtered, raw))
    row = np.array([4.0, 2.0, -0.45, 0.5, 0.7, 0.4, np.pi + 0.6])  # front, side, top lit
    rows = row + np.vstack([np.zeros(7), np.diag(box.STEPS)])
    like = np.repeat(row[None], len(rows), axis=0)
    shapes = (box, ellipsoid, cylinder)
    device = [Problem(obs, filtered.backend, shape=shape) for shape in shapes]
    host = [HostShapeProblem(obs, shape) for shape in shapes]
    for h in host:  # the unmoved row's statistics, as a fit has them from its residual
        h.column(row)

    def on_device():
        return [[d.column(r) for r in rows] for d in device]

    def on_host():
        return [h.column_batch(rows, like) for h in host]
    start = time.perf_counter()
    on_device()
    build = time.perf_counter() - start
    on_host()
    kernel, twin = [], []
    for _ in range(3 if smoke else 7):  # interleaved, untraced (time_pair traces the twin)
        kernel += timed(on_device, 1, rt.finish)
        twin += timed(on_host, 1, lambda: None)
    k, k_spread = spread(kernel)
    return Row("model", "closed shapes: one Jacobian (8 rows) of a box, an ellipsoid and a "
               "cylinder, 3 spots; device launches vs the host batch (the default here)",
               len(rows) * len(shapes), k, statistics.median(twin), max(build - k, 0.0),
               len(rows) * len(shapes) / k, "columns", math.nan, "-", math.nan, k_spread,
               note="twin = model.forward.host_shapes, what model_on='auto' runs for <= 64 spots")


def spad_model_row(rt, smoke, model_on="auto"):
    """One frame of the paper's plate at (2, 3, 0) located by the model fit from every spot of
    a 32 x 32 SPAD patch (3 cm pitch, 60,042 bins: `reproduce beyond`'s "model on all 1,024
    spots"), whole `nl.locate` calls; target: <= 1 s on 1,024 spots. Smoke: 8 x 8 spots.
    model_on: the estimator's ('kernel': the plates by ops/plate_model.py)."""
    from ...core.grid import Grid
    from ...localization.model import ModelEstimator
    from ...physics import layouts
    from ...physics.scene import Scene, Target, paper_setup
    n = 8 if smoke else 32
    spots = layouts.spad_patch((-1.0, 0.0, 0.0), (n, n), (0.03, 0.03))
    truth = (2.0, 3.0, 0.0)
    mesh = nl.rectangle(0.3, 1.6, centre=truth, cell_m=0.05 if smoke else 0.01)
    clean = nl.simulate(Scene(paper_setup(detector_spots=spots), Target(mesh), truth=truth),
                        backend=rt)
    noisy = nl.add_noise(clean, 10.0, seed=0).histograms()
    filtered = nl.gauss_filter(noisy)
    grid = Grid() if not smoke else Grid.from_ranges(x=(1, 3), y=(2, 4), step_m=0.02)

    def run():
        return nl.locate(filtered, grid, log_mode=True, raw=noisy,
                         estimator=ModelEstimator(model_on=model_on)).error_m
    start = time.perf_counter()
    error = run()
    build = time.perf_counter() - start
    kernel = timed(run, 1 if smoke else 3, rt.finish)
    k, k_spread = spread(kernel)
    how = "" if model_on == "auto" else f", model_on='{model_on}'"
    return Row("model", f"SPAD patch: {n * n} spots x {noisy.layout.time_axis.n_bins} bins, "
               f"one frame located by the model fit (nl.locate){how}", 1, k, math.nan,
               max(build - k, 0.0), 1 / k, "frames", math.nan, "-", math.nan, k_spread,
               note=f"error {error:.4f} m; no twin")


def all_rows(rt, smoke=False, say=print):
    """Every row, in the order the page gives them. The model rows time the paper's scene,
    whose collinear spots hold the height: its note is about the bench's scene, not the
    user's data, so it is not said (nothing else is kept off the terminal)."""
    import warnings
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"height \(up the wall\) is unobservable")
        return _rows(rt, smoke, say)


def _rows(rt, smoke, say):
    say("operations")
    rows = list(operation_rows(rt, smoke, say))
    say("locate: coarse to fine against exhaustive and peers")
    from .scoring import scoring_rows
    rows.extend(scoring_rows(rt, smoke, Row))
    say("pipeline")
    rows.append(pipeline_row(rt, smoke))
    say("model: closed shapes, device against the host batch")
    rows.append(closed_shapes_row(rt, smoke))
    say("model: a SPAD patch located from every spot")
    rows.append(spad_model_row(rt, smoke))
    rows.append(spad_model_row(rt, smoke, model_on="kernel"))
    say("stream: plans and the tracker, host frames to track states")
    from .stream import cold_row, crossing_row, stream_rows
    rows.extend(stream_rows(rt, smoke, Row))
    say("stream: one frame located cold, against the paper's argmax")
    rows.append(cold_row(rt, smoke, Row))
    say("stream: two targets crossing, tracked")
    rows.append(crossing_row(rt, smoke, Row))
    return rows
