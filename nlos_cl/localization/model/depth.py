"""Can these spots see how deep a target is? A probe of the fitted plate against boxes behind it.

A plate that explains the data is the visible surface of whatever is there: a plate, or the
front of a closed object whose sides the spots see too faintly to tell. Two questions, each
answered with a few forward calls and no fit:

- Would a box behind the plate explain the data better? Boxes of depth PROBE_DEPTHS x the
  plate's width, same front face, amplitude refitted: if one costs less than the plate, the
  closed shapes are worth fitting even though the plate passed the misfit test (that test has
  little power against this one alternative: a box seen mostly face-on left a plate at Birge
  ratio 1.7 under a limit of 1.9, where the box's BIC gain was 21).
- Could the data tell the plate from such a box at all? The box's amplitude-refitted distance
  from the plate's own fitted mean, in noise units (chi^2 / kappa, as the BIC's), gives the
  depth's sd to first order: sd = d / sqrt(dchi2). Above DEPTH_SD_LIMIT_M the centre along the
  normal is not determined by these spots, and the answer says so (`DEPTH_WARNING`).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from . import box, plate

PROBE_DEPTHS = (0.5, 1.0)  # times the plate's width: a box's depth is of the order of its width
MIN_PROBE_M = 0.1
DEPTH_SD_LIMIT_M = 0.2  # the centre's sd along the normal is half of it: the goal's 0.10 m
DEPTH_WARNING = ("the spots see only the front of target {k}: if it is a closed object, its "
                 "centre lies behind the found surface by half its depth, which these spots "
                 "cannot measure (depth sd {sd:.2f} m); spots farther apart see its sides")


def probe(problem, plate_result, kappa: float) -> dict:
    """{box_better: a box behind the plate costs less on the data, depth_sd_m: the depth's sd
    predicted at a box as deep as the plate is wide, depth_probe_m: that depth}."""
    from .likelihood import Problem
    q = np.asarray(plate_result.params[0], float)
    width = max(float(q[plate.WIDTH]), MIN_PROBE_M)
    # Which faces a box behind the plate shows does not depend on its depth; where it shows
    # only its front, its histograms are the plate's: nothing to evaluate
    if len(_visible(box.from_plate(q, width), problem.obs)) == 1:
        return {"box_better": False, "depth_sd_m": math.inf, "depth_probe_m": width,
                "probe_box_cost": plate_result.cost}
    boxes = Problem(problem.obs, problem.backend, problem.lattice, shape=box,
                    reflectance=problem.reflectance)
    plate_cols = problem.columns(q[None])
    plate_mean = problem.mean(plate_cols, problem.linear(plate_cols))
    as_data = Problem(replace(problem.obs, y=plate_mean), problem.backend, problem.lattice)
    best, dchi2 = math.inf, 0.0
    for share in PROBE_DEPTHS:
        cols = _box_columns(problem, boxes, box.from_plate(q, share * width))
        r = problem.residual(cols, problem.linear(cols))
        best = min(best, float(r @ r))
        r = as_data.residual(cols, as_data.linear(cols))
        dchi2 = float(r @ r) / kappa  # the last probe: the deepest, depth = width
    sd = width / math.sqrt(dchi2) if dchi2 > 0 else math.inf
    problem.calls += boxes.calls
    return {"box_better": best < plate_result.cost, "depth_sd_m": sd, "depth_probe_m": width,
            "probe_box_cost": best}


def _visible(p, obs) -> list:
    """Box p's faces (centre, u, v, normal) that the laser spot lights and a wall spot sees."""
    spots, laser = np.asarray(obs.spots, float), np.asarray(obs.laser, float)
    return [f for f in box.faces(p) if box.seen(f[0], f[3], spots, laser)]


def _box_columns(problem, boxes, p) -> np.ndarray:
    """(1, D, n) box p's unit histograms. Where its visible faces are all upright (no top or
    bottom) and the plates' problem is the host's batched model, they are those faces as
    plates, summed, in one host call (the device's forward op per face cost ~8 ms of a 50 ms
    paper-scene locate); else the box model on the device (`boxes`)."""
    faces = _visible(p, problem.obs)
    if not hasattr(problem, "coarser") or any(abs(n[2]) > 1e-12 for *_, n in faces):
        return boxes.columns(p[None])
    rows = np.array([[*c, np.linalg.norm(u), np.linalg.norm(v), math.atan2(n[1], n[0])]
                     for c, u, v, n in faces])
    return problem.column_batch(rows).sum(axis=0)[None]


CLOSED_WARNING = ("the depth of target {k} is poorly determined (sd {sd:.2f} m): its centre is "
                  "uncertain by half that along its normal")


def unseen_note(shape, result, cov_all, info, k: int = 0) -> str | None:
    """The answer's notice where these spots cannot tell how deep target k is, else None: a
    plate whose probe predicts a depth sd above DEPTH_SD_LIMIT_M, or a closed shape whose
    fitted depth has such an sd."""
    if shape is plate:
        sd = info.get("depth_sd_m")
        if sd is None or not sd > DEPTH_SD_LIMIT_M:
            return None
        return DEPTH_WARNING.format(k=k + 1, sd=sd)
    n = shape.N_PARAMS
    sd = math.sqrt(max(float(cov_all[k * n + box.DEPTH, k * n + box.DEPTH]), 0.0))
    return CLOSED_WARNING.format(k=k + 1, sd=sd) if sd > DEPTH_SD_LIMIT_M else None
