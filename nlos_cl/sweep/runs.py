"""What a worker does: a batch of runs, each simulate -> noise -> filter -> locate.

A worker process builds its OpenCL runtime once (nlos_cl.device.runtime.get_runtime caches it per
process) and keeps the clean simulation of the last few scenes, so the runs of one scene (seeds,
SNRs, filters, estimators) simulate it once. Nothing here depends on which worker runs a batch
or on what it ran before: a run's noise seed is its `seed` value from the study, and the
simulation is deterministic (integer atomics), so a cached scene equals a fresh one.
"""
from __future__ import annotations

import json
import math
import time
import warnings
from collections import OrderedDict
from dataclasses import replace

import numpy as np

from .study import RECORD_COLUMNS, SPECIAL, assignments, scene_of

_SCENES: OrderedDict = OrderedDict()  # scene key -> (spec, clean Signals, signal photons)
_GRIDS: dict = {}
KEEP_SCENES = 3

TIMING_COLUMNS = RECORD_COLUMNS["timings"]


def record_columns(record) -> list[str]:
    """The measured columns of a study's table, in order (all float64), then `failure`."""
    return [c for r in record for c in RECORD_COLUMNS[r]]


def run_batch(plan: dict, runs) -> list[dict]:
    """Measure every (run_id, values) of `runs`; one dict per run: run_id, the measured
    columns (NaN where a run failed) and `failure` ('' or the error)."""
    if "runner" in plan:  # a study of a function (runner.py)
        from .runner import run_calls
        return run_calls(plan, runs)
    with warnings.catch_warnings():  # e.g. 'z is unobservable' once per run: not news here
        warnings.simplefilter("ignore")
        return [run_one(plan, run_id, values) for run_id, values in runs]


def run_one(plan: dict, run_id: int, values: dict) -> dict:
    row = dict.fromkeys(record_columns(plan["record"]), math.nan)
    start, cpu = time.perf_counter(), time.process_time()
    try:
        _measure(plan, values, row)
        failure = ""
    except Exception as exc:  # noqa: BLE001 - one bad run must not end a 10^5-run study
        failure = f"{type(exc).__name__}: {exc}"[:500]
    if "t_run_s" in row:  # wall time, and CPU time of the whole process (all its threads)
        row["t_run_s"] = time.perf_counter() - start
        row["t_cpu_s"] = time.process_time() - cpu
    return {"run_id": run_id, **{k: row[k] for k in record_columns(plan["record"])},
            "failure": failure}


class _Clock:
    """Stage times; the device queue is drained before each reading, so time is charged to
    the stage that spent it."""

    def __init__(self, backend):
        self.finish = getattr(backend, "finish", lambda: None)
        self.last = time.perf_counter()

    def lap(self) -> float:
        self.finish()
        now = time.perf_counter()
        spent, self.last = now - self.last, now
        return spent


def _measure(plan: dict, values: dict, row: dict) -> None:
    from ..localization.api import gauss_filter, gauss_fit, locate
    from ..simulation.frame import add_noise
    own = {p: v for p, v in assignments(plan, values).items() if p in SPECIAL}
    h_s, how = float(own.get("h_s", plan["h_s"])), own.get("filter", plan["filter"])
    start = time.perf_counter()
    spec, clean, signal_photons, cached = _clean(plan, values)
    clock = _Clock(clean.backend)
    t_sim = 0.0 if cached else time.perf_counter() - start
    noisy = clean if spec.noise is None else add_noise(clean, model=spec.noise,
                                                          seed=int(own["seed"]))
    t_noise = clock.lap()
    if how == "gauss":
        filtered = gauss_filter(noisy, h_s)
    else:
        filtered = gauss_fit(noisy)[0] if how == "gauss_fit" else noisy
    t_filter = clock.lap()
    loc = locate(filtered, _grid(plan, filtered.layout, h_s), estimator=own["estimator"],
                    raw=noisy)
    t_locate = clock.lap()
    measured = {"t_simulate_s": t_sim, "t_noise_s": t_noise, "t_filter_s": t_filter,
                "t_locate_s": t_locate, "error_m": _float(loc.error_m)}
    measured.update(zip(RECORD_COLUMNS["position"], [*loc.position, *_truth(loc)]))
    if loc.covariance is not None:
        c = np.asarray(loc.covariance, dtype=np.float64)
        measured.update(zip(RECORD_COLUMNS["covariance"],
                            (c[0, 0], c[0, 1], c[0, 2], c[1, 1], c[1, 2], c[2, 2])))
    if "photons" in row and signal_photons is not None:
        measured["photons"] = float(noisy.histograms().data.sum(axis=1).mean())
        measured["signal_photons"] = signal_photons
    row.update({k: float(v) for k, v in measured.items() if k in row})


def _float(value) -> float:
    return math.nan if value is None else float(value)


def _truth(loc) -> list:
    return [math.nan] * 3 if loc.truth is None else list(loc.truth)


def _clean(plan: dict, values: dict):
    """(scene spec, clean Signals, mean signal photons per detector or None, was cached)."""
    from ..io.scenefile import load_scene
    from ..physics.noise import PhotonCounter
    from ..simulation.frame import simulate
    scene = scene_of(plan, values)
    key = json.dumps(scene, sort_keys=True, default=str)
    if key in _SCENES:
        _SCENES.move_to_end(key)
        return (*_SCENES[key], True)
    spec = load_scene(scene)
    clean = simulate(spec.scene, spec.time_axis)
    photons = None
    if isinstance(spec.noise, PhotonCounter):  # expected signal counts: no dark, no ambient
        quiet = replace(spec.noise, dark_count_rate_hz=0.0, ambient_rate_hz=0.0, jitter_s=0.0)
        photons = float(quiet.expected_counts(clean.histograms()).data.sum(axis=1).mean())
    _SCENES[key] = (spec, clean, photons)
    while len(_SCENES) > KEEP_SCENES:
        _SCENES.popitem(last=False)
    return spec, clean, photons, False


def _grid(plan: dict, layout, h_s: float):
    """The study's grid, or the region this layout can see (localization.region.default_region)."""
    from ..core.grid import Grid
    from ..core.histograms import HistogramSet
    from ..localization.region import default_region
    if plan["grid"] is not None:
        return Grid.from_ranges(**plan["grid"])
    cal = layout.calibration
    key = (layout.time_axis, layout.detector_spots.tobytes(), layout.laser_spot.tobytes(),
           cal.a_m_per_s, np.asarray(cal.b_m).tobytes(), h_s)
    if key not in _GRIDS:
        empty = HistogramSet.from_layout(np.zeros(layout.shape), layout)
        _GRIDS[key] = default_region(empty, h_s)
    return _GRIDS[key]


def worker_info() -> dict:
    """Build this process's OpenCL runtime (once) and say which device it chose."""
    import os

    from ..ops.opencl_backend import get_runtime
    return {"pid": os.getpid(), "device": get_runtime().name}
