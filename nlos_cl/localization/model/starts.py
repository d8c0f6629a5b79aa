"""Where the fit starts. The "centroid start": the signal-weighted mean hidden path per
detector, then the point whose ellipse paths |c - O| + |c - spot| best match those means
(on z = z0 when height is unobservable). The paper's argmax is a second candidate centre.
Around each centre, a small lattice of yaws and sizes is scored with one forward call each;
the best few start the short fits."""
from __future__ import annotations

import itertools

import numpy as np

from . import plate

YAW_OFFSETS = np.radians([-50.0, -25.0, 0.0, 25.0, 50.0])
SIZES = ((0.3, 0.8), (0.3, 1.6), (0.8, 0.8), (0.8, 1.6))


def mean_paths(obs, data=None) -> np.ndarray:
    """(D,) signal-weighted mean hidden path per detector (background removed for counts)."""
    y = obs.y if data is None else data
    if obs.mode == "poisson":
        edge = np.concatenate([y[:, :5], y[:, -5:]], axis=1).mean(axis=1, keepdims=True)
        y = y - edge
    w = np.maximum(y, 0.0) * obs.valid
    total = np.maximum(w.sum(axis=1), 1e-300)
    return (w * obs.centres()).sum(axis=1) / total


def ellipse_point(obs, paths, z0=0.0, free_z=False) -> np.ndarray:
    """The point (y > 0) whose paths to the laser and each spot best match `paths`."""
    from .lm import least_squares  # not SciPy's: its import costs a one-shot locate ~0.25 s
    spots, laser = obs.spots, obs.laser
    x0 = float(np.reshape(laser, (-1, 3))[:, 0].mean())  # a paired layout: its lasers' middle

    def res(v):
        c = np.array([v[0], v[1], v[2] if free_z else z0])
        return np.linalg.norm(c - laser, axis=-1) + np.linalg.norm(spots - c, axis=1) - paths

    best = None
    reach = float(np.median(paths)) / 2
    for gx, gy in ((0.5, 0.7), (0.9, 0.3), (0.2, 0.9)):
        v0 = [x0 + gx * reach, max(gy * reach, 0.1)] + ([z0] if free_z else [])
        lo = [-np.inf, 0.05] + ([-np.inf] if free_z else [])
        sol = least_squares(res, v0, bounds=(lo, np.inf))
        if best is None or sol.cost < best.cost:
            best = sol
    v = best.x
    return np.array([v[0], v[1], v[2] if free_z else z0])


def candidates(centres, laser, sizes=SIZES, yaw_offsets=YAW_OFFSETS) -> np.ndarray:
    """Plate rows (N, 6) around each centre: every yaw offset from facing O, every size."""
    rows = []
    for c, (w, h), dyaw in itertools.product(centres, sizes, yaw_offsets):
        rows.append([c[0], c[1], c[2], w, h, plate.facing(c, laser) + dyaw])
    return np.array(rows)


def best_starts(problem, rows, fixed=None, keep=3) -> list[np.ndarray]:
    """Score each candidate row (with the plates in `fixed` alongside) by its profiled cost;
    return the `keep` best, distinct in centre or yaw."""
    fixed_cols = problem.columns(fixed) if fixed is not None and len(fixed) else None
    costs = []
    for p in rows:
        col = problem.column(p)[None]
        cols = col if fixed_cols is None else np.concatenate([fixed_cols, col])
        r = problem.residual(cols, problem.linear(cols))
        costs.append(float(r @ r))
    chosen, yaw = [], getattr(problem, "shape", plate).YAW
    for i in np.argsort(costs):
        p = rows[i]
        if all(np.linalg.norm(p[:3] - q[:3]) > 0.05 or abs(p[yaw] - q[yaw]) > 0.3
               or abs(p[plate.WIDTH] - q[plate.WIDTH]) > 0.2 for q in chosen):  # (width: 4th in all)
            chosen.append(p)
        if len(chosen) == keep:
            break
    return chosen


def start_centres(obs, argmax_position, free_z, z0, data=None) -> list[np.ndarray]:
    """The centroid start and (where it differs by more than 5 cm) the paper's argmax."""
    centroid = ellipse_point(obs, mean_paths(obs, data), z0, free_z)
    out = [centroid]
    if argmax_position is not None:
        a = np.array(argmax_position, dtype=np.float64)
        if not free_z:
            a[2] = z0
        if np.linalg.norm(a - centroid) > 0.05 and a[1] > 0.05:
            out.append(a)
    return out

