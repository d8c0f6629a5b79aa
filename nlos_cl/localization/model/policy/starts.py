"""Where the fit starts. The "centroid start": the signal-weighted mean hidden path per
detector, then the point whose ellipse paths |c - O| + |c - spot| best match those means
(the held axis on its plane where collinear spots cannot see it: plate.Held). The paper's
argmax is a second candidate centre.
Around each centre, a small lattice of yaws and sizes is scored with one forward call each;
the best few start the short fits."""
from __future__ import annotations

import itertools

import numpy as np

from ....core.stats import median
from ..shapes import plate

YAW_OFFSETS = np.radians([-50.0, -25.0, 0.0, 25.0, 50.0])
SCORE_ROWS = 20  # candidates evaluated per call: 20 x 1,024 detectors x 600 samples = 98 MB
SIZES = ((0.3, 0.8), (0.3, 1.6), (0.8, 0.8), (0.8, 1.6))
# One target's candidates are ranked on a coarser lattice than the fit's (a quarter of the
# points; the cells' blur and shift keep the coarse model smooth). Against the fit's lattice:
# the same starts and fits (0.0000 mm) on the paper's scene (3 seeds) and the first 10 draws of
# `reproduce draws` "one"; at (4, 6) one start of one frame changed, its fit by 0.009 mm. (The
# host model only, model.batch.HostProblem: the closed shapes' candidates keep their lattice.)
START_LATTICE = (8, 12)


def start_lattice(lattice):
    """The candidates' lattice for a fit on `lattice`: START_LATTICE (or the fit's, if
    coarser); for counts (a plate.Lattice: model.lattices.counts_lattice) half its cells each
    way with its blur share, as (8, 12) is half the filtered (16, 24): at counts' pulse (8, 12)
    combs (cells of ~12 cm of path against a pulse of ~1.3 cm) and ranks the candidates by a
    model that is not the fit's."""
    if isinstance(lattice, plate.Lattice):
        return plate.Lattice(-(-lattice[0] // 2), -(-lattice[1] // 2), lattice.blur_share,
                             lattice.depth_cells)
    return tuple(min(a, b) for a, b in zip(START_LATTICE, lattice))


def mean_paths(obs, data=None) -> np.ndarray:
    """(D,) signal-weighted mean hidden path per detector (background removed for counts);
    NaN for a detector without signal above it (a CC-SOCR scan point whose counts are all 0).
    In float64: a float32 record's sum of 0 would stay 0 under a 1e-300 floor (0 / 0)."""
    y = np.asarray(obs.y if data is None else data, dtype=np.float64)
    if obs.mode == "poisson":
        edge = np.concatenate([y[:, :5], y[:, -5:]], axis=1).mean(axis=1, keepdims=True)
        y = y - edge
    w = np.maximum(y, 0.0) * obs.valid
    total = w.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0, (w * obs.centres()).sum(axis=1) / total, np.nan)


def ellipse_point(obs, paths, held=plate.Held()) -> np.ndarray:
    """The point (y > 0) whose paths to the laser and each spot best match `paths` (its held
    axis, if any, on the held plane); detectors whose path is NaN (no signal) left out, and
    the region's middle (held.at) where none has one."""
    from ..solve.lm import (
        least_squares,  # not SciPy's: its import costs a one-shot locate ~0.25 s
    )
    seen = np.isfinite(paths)
    if not seen.any():
        return held.put(held.at)
    laser = obs.laser[seen] if np.ndim(obs.laser) == 2 else obs.laser
    spots, paths = obs.spots[seen], np.asarray(paths)[seen]
    x0 = float(np.reshape(laser, (-1, 3))[:, 0].mean())  # a paired layout: its lasers' middle
    axes = held.free_axes()

    def point(v):
        c = held.put(held.at)
        c[axes] = v
        return c

    def legs(v):  # from the laser and from each spot to c, and their lengths
        c = point(v)
        to_laser, to_spots = c - laser, c - spots
        return (to_laser, np.sqrt(np.sum(to_laser * to_laser, axis=-1)), to_spots,
                np.sqrt(np.sum(to_spots * to_spots, axis=1)))

    def res(v):
        _, r1, _, r2 = legs(v)
        return r1 + r2 - paths

    def jac(v):  # the unit vectors along both legs (y >= 0.05: c is never on the wall)
        d1, r1, d2, r2 = legs(v)
        return (d1 / np.expand_dims(r1, -1) + d2 / r2[:, None])[:, axes]

    best = None
    reach = median(paths) / 2
    lo = np.array([-np.inf, 0.05, -np.inf])[axes]
    for gx, gy in ((0.5, 0.7), (0.9, 0.3), (0.2, 0.9)):
        v0 = np.array([x0 + gx * reach, max(gy * reach, 0.1), held.at[2]])[axes]
        sol = least_squares(res, v0, jac=jac, bounds=(lo, np.inf))
        if best is None or sol.cost < best.cost:
            best = sol
    return point(best.x)


def candidates(centres, laser, sizes=SIZES, yaw_offsets=YAW_OFFSETS) -> np.ndarray:
    """Plate rows (N, 6) around each centre: every yaw offset from facing O, every size."""
    rows = []
    for c, (w, h), dyaw in itertools.product(centres, sizes, yaw_offsets):
        rows.append([c[0], c[1], c[2], w, h, plate.facing(c, laser) + dyaw])
    return np.array(rows)


def best_starts(problem, rows, fixed=None, keep=3) -> list[np.ndarray]:
    """Score each candidate row (with the plates in `fixed` alongside) by its profiled cost;
    return the `keep` best, distinct in centre or yaw. (The rows go to column_batch
    SCORE_ROWS at a time: the host model evaluates each group in one call, in bounded memory.)"""
    scorer, lattice = problem, start_lattice(problem.lattice)
    if fixed is None and problem.plates_on_host and tuple(lattice) != tuple(problem.lattice):
        scorer = problem.coarser(lattice)  # see START_LATTICE
    calls, model_s = scorer.calls, scorer.model_s
    chosen = _best(scorer, rows, fixed, keep)
    if scorer is not problem:  # the problem counts every plate evaluated for it
        problem.calls += scorer.calls - calls
        problem.model_s += scorer.model_s - model_s
    return chosen


def _best(problem, rows, fixed, keep):
    fixed_cols = problem.columns(fixed) if fixed is not None and len(fixed) else None
    costs, rows = [], np.asarray(rows, np.float64)
    lower, upper = problem.shape.LOWER, problem.shape.UPPER
    if rows.shape[-1:] == np.shape(lower):
        # starts outside the fit's bounds are not scored: a rounder start from a plate (depth
        # 0: ellipsoid.rounder_sizes' sqrt(w d) = 0) divided by a zero semi-axis, and its NaN
        # cost was never chosen (clipping it into the bounds instead changed which starts win:
        # tests/localization/model/test_model_depth.py's box came back a plate)
        inside = np.all((rows >= lower) & (rows <= upper), axis=1)
        rows = rows[inside] if inside.any() else rows
    alone = fixed_cols is None and problem.obs.mode == "gauss"
    for at in range(0, len(rows), SCORE_ROWS):  # (B, D, n) floats: bounded, B <= SCORE_ROWS
        batch = problem.column_batch(rows[at:at + SCORE_ROWS])
        if alone:
            costs.extend(_costs_alone(problem.obs, batch))
            continue
        for col in batch:
            cols = col[None] if fixed_cols is None else np.concatenate([fixed_cols, col[None]])
            lin = problem.linear(cols)
            r = problem.residual(cols, lin)
            costs.append(float(r @ r) if plausible(lin, len(cols)) else np.inf)
    chosen, yaw = [], problem.shape.YAW
    for i in np.argsort(costs):
        p = rows[i]
        if all(np.linalg.norm(p[:3] - q[:3]) > 0.05 or abs(p[yaw] - q[yaw]) > 0.3
               or abs(p[plate.WIDTH] - q[plate.WIDTH]) > 0.2 for q in chosen):  # (width: 4th in all)
            chosen.append(p)
        if len(chosen) == keep:
            break
    return chosen


def _costs_alone(obs, cols) -> np.ndarray:
    """Each column's (B, D, n) profiled cost as the only target of a Gaussian observation, all
    at once: what Problem.linear and .residual give for one column (its amplitude by weighted
    least squares, >= 0, and the weighted residual's sum of squares), in closed form."""
    a = (cols / obs.noise[None, :, None]).reshape(len(cols), -1)
    b = (obs.y / obs.noise[:, None]).reshape(-1)
    norm2 = np.einsum("ij,ij->i", a, a)
    amp = np.maximum(a @ b, 0.0) / np.where(norm2 > 0, norm2, 1.0)  # a plate unseen: 0
    r = b[None] - amp[:, None] * a
    return np.einsum("ij,ij->i", r, r)


# The brightest target's amplitude over the faintest's at most: the amplitudes of one frame
# share its unknown power scale, so their ratio is one of reflectances (albedo 1 against 1 %).
# A plate grazing the wall far to the side, whose four cosines are ~1e-3, fits a residual
# sliver with an amplitude 400-10,000x the real targets' (4 of 7 failed draws with several
# targets held one) and takes the place of the target it should have found.
MAX_AMPLITUDE_RATIO = 100.0


def plausible(lin, k: int) -> bool:
    """Are the K targets' amplitudes (lin[:k], >= 0) within MAX_AMPLITUDE_RATIO of each
    other? (A zero amplitude, a target the data do not need, is left to the fit's report.)"""
    a = np.asarray(lin[:k], float)
    a = a[a > 0]
    return len(a) < 2 or float(a.max()) <= MAX_AMPLITUDE_RATIO * float(a.min())


def start_centres(obs, argmax_position, held, data=None) -> list[np.ndarray]:
    """The centroid start and (where it differs by more than 5 cm) the paper's argmax."""
    centroid = ellipse_point(obs, mean_paths(obs, data), held)
    out = [centroid]
    if argmax_position is not None:
        a = held.put(argmax_position)
        if np.linalg.norm(a - centroid) > 0.05 and a[1] > 0.05:
            out.append(a)
    return out



# Residual backprojection (the paper's joint likelihood on what the fitted targets leave): the
# grid's cells, at most this many along x (y, z in proportion), and how far apart the
# centres it proposes lie from each other and from the targets already fitted.
RESIDUAL_CELLS_X = 48
RESIDUAL_APART_M = 0.4


def _reach_box(obs, held):
    """Axis ranges (x, y, z) that hold every point whose ellipse path to some detector lies
    inside its sample window: half the longest path around the wall spots (the held axis: its
    value)."""
    top = float(np.max(obs.path0 + obs.dpath * (obs.n - 1)))
    wall = np.vstack([obs.spots, np.reshape(obs.laser, (-1, 3))])
    half = 0.5 * top
    out = [(wall[:, 0].min() - half, wall[:, 0].max() + half), (0.05, half),
           (wall[:, 2].min() - half, wall[:, 2].max() + half)]
    if held.axis is not None:
        out[held.axis] = (held.value, held.value)
    return out


def residual_centres(obs, z, existing, held, count=3) -> list[np.ndarray]:
    """Up to `count` centres where the residual `z` (D, n, in noise units) holds a target the
    fit has not explained: on a coarse grid over the region the windows reach, each cell sums
    over the detectors log(max(z, 1)), z at the cell's ellipse path (max-
    filtered over the path a cell spans, so the coarse grid misses no peak). The product form
    wants every detector to see the target, which one detector's misfit of a fitted strong
    target cannot fake. Cells within RESIDUAL_APART_M of `existing` centres are skipped.
    With many targets, the weak one 4x farther carried 1/400 of the signal energy: the
    centroid of the residual (start_centres) sat between the misfits, this finds it."""
    xr, yr, zr = _reach_box(obs, held)
    across = zr if held.axis == 0 else xr  # the wall's long way: x, or z where x is held
    step = (across[1] - across[0]) / RESIDUAL_CELLS_X
    axes = [np.arange(lo + 0.5 * step, hi, step) if hi - lo > step else np.array([lo])
            for lo, hi in (xr, yr, zr)]
    cells = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    z = np.where(obs.valid, z, 0.0)
    half = max(1, int(np.ceil(step * 1.8 / float(np.min(obs.dpath)))))  # path moves <= 2 step
    from numpy.lib.stride_tricks import sliding_window_view
    padded = np.pad(z, ((0, 0), (half, half)), constant_values=0.0)
    zmax = sliding_window_view(padded, 2 * half + 1, axis=1).max(axis=-1)
    lasers = np.broadcast_to(np.reshape(obs.laser, (-1, 3)), obs.spots.shape)
    score = np.zeros(len(cells))
    for d in range(len(obs.spots)):
        path = (np.linalg.norm(cells - lasers[d], axis=1)
                + np.linalg.norm(cells - obs.spots[d], axis=1))
        idx = np.rint((path - obs.path0[d]) / obs.dpath[d]).astype(np.int64)
        inside = (idx >= 0) & (idx < obs.n)
        score += np.where(inside, np.log(np.maximum(zmax[d, np.clip(idx, 0, obs.n - 1)], 1.0)),
                          0.0)
    chosen = [np.asarray(c, float) for c in existing]
    out = []
    for i in np.argsort(-score):
        if score[i] <= 0 or len(out) == count:
            break
        if all(np.linalg.norm(cells[i] - c) > RESIDUAL_APART_M for c in chosen):
            out.append(cells[i].copy())
            chosen.append(cells[i])
    return out
