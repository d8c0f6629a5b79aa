"""Where the model fit's plates run fastest, by the number of histograms: one Jacobian's
plates (the unmoved plate and its 6 stepped ones, with the unmoved plate's cell statistics, as
model.fit asks them) evaluated by each path on the same observation of the same frame:

- host: model.forward.batch.HostProblem, float64 NumPy (one laser spot only);
- kernel: the same problem by the plate_model operation (HostProblem(kernel=True));
- forward op: model.forward.likelihood.Problem, the registered forward operation, a call per plate.

Layouts: one laser spot and D spots on a square SPAD-like patch, and a confocal scan (each
spot its own laser spot) of the same spots. `auto` names the path ModelEstimator(model_on=
'auto') takes there (estimator.plates_path), `fastest` the one measured fastest: the table
shows where the rule and the measurement agree."""
from __future__ import annotations

import math
import statistics
import time

import numpy as np

SIZES = (3, 16, 64, 256, 1024, 4096)
SMOKE_SIZES = (3, 16)
PATHS = ("host", "kernel", "forward op")


def _spots(count):
    """`count` wall spots: the paper's 3, else a square patch of about `count` (2 cm pitch)."""
    from ...physics import layouts
    from ...physics.scene import paper_setup
    if count == 3:
        return paper_setup().detector_spots
    side = int(round(math.sqrt(count)))
    return layouts.spad_patch((-1.0, 0.0, 0.0), (side, side), (0.02, 0.02))


def _observation(rt, count, confocal):
    """The model fit's Observation of one noisy frame (10 dB) of the paper's plate at (2, 3, 0)
    seen from `count` spots, 10 ps bins. Confocal: the same samples with each spot its own
    laser spot and the windows moved to the confocal paths (2 |c - s| for the plate's centre
    c): the work of a confocal scan's fit, without simulating a laser per spot."""
    import dataclasses

    import nlos_cl as nl
    from ...core.grid import Grid
    from ...localization.estimate import Scored
    from ...localization.model import ModelEstimator
    from ...physics.scene import Scene, Target, paper_setup
    setup = paper_setup(detector_spots=_spots(count))
    truth = np.array([2.0, 3.0, 0.0])
    scene = Scene(setup, Target(nl.rectangle(0.3, 1.6, centre=truth, cell_m=0.04)), truth=truth)
    clean = nl.simulate(scene, nl.default_time_axis(setup, 10e-12), backend=rt)
    raw = nl.add_noise(clean, 10.0, seed=1)
    filtered = nl.gauss_filter(raw)
    obs = ModelEstimator().observation(Scored(rt, None, Grid(), True, count, filtered, raw))
    if not confocal:
        return obs
    to_spot = np.linalg.norm(obs.spots - truth, axis=1)
    move = 2 * to_spot - (to_spot + float(np.linalg.norm(obs.laser - truth)))
    return dataclasses.replace(obs, laser=obs.spots.copy(), edge0=obs.edge0 + move,
                               path0=obs.path0 + move)


def _problems(rt, obs):
    """{path: problem} for the paths that model this layout."""
    from ...localization.model.forward.batch import HostProblem
    from ...localization.model.forward.likelihood import Problem
    from ...localization.model.shapes.lattices import lattice_for
    lattice = lattice_for(obs)
    out = {"kernel": HostProblem(obs, lattice, rt, kernel=True), "forward op":
           Problem(obs, rt, lattice)}
    if np.ndim(obs.laser) == 1:
        out["host"] = HostProblem(obs, lattice, rt)
    return out


def _jacobian_rows():
    from ...localization.model.shapes import plate
    base = np.array([2.0, 3.0, 0.0, 0.3, 1.6, math.pi])
    rows = [base] + [base + plate.STEPS[i] * (np.arange(6) == i) for i in range(6)]
    return np.array(rows), np.repeat(base[None], 7, axis=0)


def path_times(rt, count, confocal, repeats=3):
    """{path: median seconds of one Jacobian's 7 plates} and the observation's samples."""
    obs = _observation(rt, count, confocal)
    rows, like = _jacobian_rows()
    times = {}
    problems = _problems(rt, obs)
    for name in PATHS:  # a warm-up each, then the paths interleaved
        if name in problems:
            problems[name].column_batch(rows, like)
    runs = {name: [] for name in problems}
    for _ in range(repeats):
        for name, problem in problems.items():
            start = time.perf_counter()
            problem.column_batch(rows, like)
            rt.finish()
            runs[name].append(time.perf_counter() - start)
    for name, values in runs.items():
        times[name] = statistics.median(values)
    return times, obs.y.size


def table(rt, smoke=False, say=print) -> list[dict]:
    """One row per (layout, size): each path's time, the rule's choice and the fastest."""
    from ...localization.model.estimator import plates_path
    out = []
    for confocal in (False, True):
        for count in SMOKE_SIZES if smoke else SIZES:
            say(f"model paths: {'confocal' if confocal else 'one laser'}, {count} spots")
            times, samples = path_times(rt, count, confocal, 1 if smoke else 3)
            out.append({"layout": "confocal" if confocal else "one laser", "spots": count,
                        "samples": samples, **{k: times.get(k, math.nan) for k in PATHS},
                        "auto": plates_path("auto", count, confocal),
                        "fastest": min(times, key=times.get)})
    return out


def markdown(rows) -> str:
    """The table as markdown (ms; '-' where a path cannot model the layout)."""
    head = ("| layout | spots | samples | host (ms) | kernel (ms) | forward op (ms) | auto takes "
            "| fastest |\n|---|---:|---:|---:|---:|---:|---|---|\n")

    def ms(v):
        return "-" if not math.isfinite(v) else f"{1e3 * v:.1f}"
    return head + "".join(
        f"| {r['layout']} | {r['spots']} | {r['samples']} | {ms(r['host'])} | "
        f"{ms(r['kernel'])} | {ms(r['forward op'])} | {r['auto']} | {r['fastest']} |\n"
        for r in rows)


def section(rows) -> str:
    """The table under its heading, for the bench's page and terminal; '' without rows."""
    if not rows:
        return ""
    return ("\n## The model's plates by number of histograms: host, kernel or forward op\n\n"
            "One Jacobian's 7 plates (the plate and its 6 stepped rows) on the same observation "
            "of one 10 dB frame, median of 3 interleaved runs after a warm-up (nlos_cl/apps/"
            "bench/model_paths.py). `auto takes`: the path ModelEstimator(model_on='auto') "
            "runs there; `fastest`: the path measured fastest in this run.\n\n"
            + markdown(rows) + "\n")
