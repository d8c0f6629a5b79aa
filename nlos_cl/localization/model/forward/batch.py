"""Plates evaluated on the host, many per call: the model of model.plate and the
forward operation's fast path (deposit + correlation, ops/forward.py), in float64 NumPy and
vectorised over a batch of parameter rows.

Why: a warm-started fit (a tracker's next frame, nlos_cl.localization.model.policy.warm) needs ~25 model
evaluations of a tiny problem (3 detectors x ~80 samples, 1,536 point facets). One call of
the registered `forward` op costs ~1 ms there whatever the work (launches, two read-backs)
plus ~0.7 ms of cell statistics on the host; a Jacobian's 5 plates in one host call cost
about as much as three single ones. ModelEstimator(model_on='auto')
uses it for plate fits (cold and warm) with up to HOST_DETECTORS detectors.

Same model as `Problem.column`: each plate's own cell statistics (`plate.cell_model`: Gauss
points pulled in, shared blur, per-detector shift), its own pulse width, bins integrated over
their width. The deposit (model.deposit) splits each point's weight linearly between the two
sub-bins around its path (sub-bins of at most sigma / SUB_BINS_PER_SIGMA, as the kernel), then
correlates with the bin-integrated pulse per sub-bin phase; the split errs by <= (dsub /
sigma)^2 / 8 = 2e-4 of the peak (the kernel's bound), and float64 has no float32 path rounding.

Half a plate's cost is its cell statistics (the Gauss points' paths to STAT_SPOTS spots). A
Jacobian's or a covariance's moved plates borrow their unmoved plate's statistics
(`column_batch(rows, like)`, remembered from the call that evaluated it): a warm stream frame
26.5 -> 21 ms (with CHUNK_ROWS), derivatives within 0.2 % (model.fit's docstring).
"""
from __future__ import annotations

import math
import time

import numpy as np

from ....core.allocator import keep_freed_memory
from ....core.constants import TINY
from ....core.geometry import distance, spot_legs
from ....core.stats import unique_sorted
from ....ops.forward import SUB_BINS_PER_SIGMA

# plate_model's cap (a plate's points in the 32 KiB of local memory every device has)
from ....ops.plate_model import MAX_CELLS as MAX_KERNEL_CELLS
from ..shapes import plate
from .deposit import deposit_bins
from .likelihood import Problem
from .shadow import occluders_of, shade

# Rows per NumPy pass: at least CHUNK_ROWS, and as many as keep a pass within PASS_PAIRS
# point-detector pairs (its temporaries grow with them: bounded memory). With core.allocator
# keeping freed memory, one pass of up to 16 plates (3 spots, 1,536 points each) is the faster:
# the stream bench's cold frames 39 ms (32 and 64 rows the same as 16).
CHUNK_ROWS = 6
PASS_PAIRS = 16 * 1536 * 3
HISTS_BYTES = 32 * 2 ** 20  # the remembered histograms at most (HostProblem._hists)


def rows_per_pass(lattice, n_spots: int) -> int:
    """Plates a NumPy pass evaluates (PASS_PAIRS, CHUNK_ROWS): 2 x 2 Gauss points a cell."""
    return max(CHUNK_ROWS, PASS_PAIRS // (4 * lattice[0] * lattice[1] * n_spots))


class HostProblem(Problem):
    """A `Problem` (plates only) whose model runs on the host, a batch of rows per call, with
    the plates' mutual shadows (`columns`, `occluders`: model.shadow).
    A Jacobian's or a covariance's moved plates (`column_batch(rows, like)`) are evaluated with
    the unmoved plate's cell statistics: d(model)/d(parameter) at frozen blur, shift and
    pull-in, half the work of a column; residuals use each plate's own."""

    batched = True  # column_batch: one host call (or one launch) for all rows
    plates_on_host = True

    def __init__(self, obs, lattice=(16, 24), backend=None, reflectance=None, kernel=False):
        # backend: for the closed shapes' Problems. reflectance: None (Lambertian) or a model
        # with factor_of_cosines (its factor from n.l, n.v and l.v: GGX, Retroreflective),
        # applied to the points' weights; the cell statistics (pull-in, blur, shift) stay Lambertian's.
        # kernel: evaluate the plates with the plate_model operation on `backend` (the same
        # model in float32, many plates a launch: ops/plate_model.py) where it has them: a
        # Lambertian plate no other plate shadows, on a lattice of <= MAX_KERNEL_CELLS cells;
        # with a laser spot per detector (confocal, paired: `paired`) only the kernel has the
        # model (the host's passes here know one laser spot), and no shadows are modelled
        super().__init__(obs, backend, lattice, reflectance=reflectance)
        self.paired = np.ndim(obs.laser) == 2
        self.kernel = bool(kernel) and backend is not None and reflectance is None and \
            lattice[0] * lattice[1] <= MAX_KERNEL_CELLS
        self._plan = None  # the plate_model operation's Plan (plates_on_device), made once
        keep_freed_memory()  # core.allocator: the deposit's passes 4x faster with it
        # False: every plate alone, as likelihood.Problem (comparisons; paired layouts)
        self.shadows = not self.paired
        self._factor = None if reflectance is None else reflectance.factor_of_cosines
        floor = math.sqrt(max(obs.sigma0_m ** 2 - obs.box_excess_m2, TINY))
        # one sub-bin count per observation (from the narrowest pulse any plate can have):
        # a plate's histograms do not depend on which batch it is evaluated in
        self.os = max(1, int(math.ceil(float(np.max(obs.dpath)) * SUB_BINS_PER_SIGMA / floor)))
        self._stats = {}  # row bytes -> its cell statistics (_remember, _statistics_of)
        self._hists = {}  # row bytes -> its histograms, evaluated with its own statistics
        self._keep_hists = int(min(64, HISTS_BYTES // max(8 * obs.y.size, 1)))
        self._taps = {}  # (pad, scale) -> the deposit's taps (model.deposit.taps_of)
        self._some = _statistics_spots(len(obs.spots))
        self._stat_spots = obs.spots[self._some]  # the cell statistics' spots
        self._affine = _affine_spread(obs, self._some, self.paired)
        self._coarser = {}

    def column(self, p) -> np.ndarray:
        return self.column_batch(np.asarray(p, float)[None])[0]

    def coarser(self, lattice) -> "HostProblem":
        """This observation's model on another lattice (one kept per cells, share, depth)."""
        key = (tuple(lattice), plate.flat_share(lattice), getattr(lattice, "depth_cells", None))
        if key not in self._coarser:
            self._coarser[key] = HostProblem(self.obs, lattice, self.backend, self.reflectance,
                                             self.kernel)
        return self._coarser[key]

    def column_batch(self, rows, like=None, occluders=None) -> np.ndarray:
        """(B, D, n) unit-amplitude histograms of B plates (rows (B, 6)). like: None, or
        (B, 6) rows whose cell statistics each plate borrows instead of its own (a Jacobian's
        plates, each a small step from `like`: fit._Objective.jac; the statistics of rows
        evaluated in the last calls are remembered, so they cost nothing there). occluders:
        None, or per row the (K', 6) plate rows that shadow it (model.shadow). A plate
        evaluated with its own statistics and occluders in the last calls is not evaluated
        again (a start the short fit begins at, the short fit's end the final fit begins at)."""
        rows = np.atleast_2d(np.asarray(rows, np.float64))
        occ = [None] * len(rows) if occluders is None else \
            [None if o is None or not len(o) else np.asarray(o, np.float64) for o in occluders]
        own = [None if like is not None and not np.array_equal(r, q) else
               r.tobytes() + (b"" if o is None else o.tobytes())
               for r, q, o in zip(rows, rows if like is None else like, occ)]
        out = np.empty((len(rows),) + self.obs.y.shape)
        todo = []
        for i, key in enumerate(own):
            if key in self._hists:
                out[i] = self._hists[key]
            else:
                todo.append(i)
        if len(self._hists) > self._keep_hists:
            self._hists.clear()
        chunk = rows_per_pass(self.lattice, len(self.obs.spots))
        for at in range(0, len(todo), chunk):
            part = todo[at:at + chunk]
            out[part] = self._evaluate(rows[part], None if like is None else like[part],
                                       [occ[i] for i in part])
            if self._keep_hists:  # copies: the caller may change what it is given
                self._hists.update((own[i], out[i].copy()) for i in part if own[i] is not None)
        return out

    def _evaluate(self, rows, like, occluders=None) -> np.ndarray:
        if self.kernel and (occluders is None or all(o is None for o in occluders)):
            from .plates_on_device import evaluate
            return evaluate(self, rows, like)
        if self.paired:
            raise NotImplementedError("obs.laser: the host plate model knows one laser spot; "
                                      "use kernel=True with a backend, or likelihood.Problem")
        t = time.perf_counter()
        obs = self.obs
        stats = None if like is None else self._statistics_of(np.atleast_2d(like))
        points, normal, area, stats = _plate_points(rows, self.lattice, self._stat_spots,
                                                    obs.laser, stats)
        if like is None:
            self._remember(rows, stats)
        _, blur2, shift = stats
        shift = self._spread(shift)
        sigma = np.sqrt(obs.sigma0_m ** 2 + blur2 - obs.box_excess_m2)  # (B,)
        points = points.reshape(len(rows), -1, 3)
        path, weight = _paths(points, normal, area / 4.0, obs.spots, obs.laser, self._factor)
        weight = shade(weight, points, rows, occluders, self.lattice, obs.laser, obs.spots)
        hist = deposit_bins(path, weight, obs.edge0[None] - shift, obs.dpath, sigma, obs.n,
                            self.os, self._taps)
        self.calls += len(rows)
        self.model_s += time.perf_counter() - t
        return np.where(obs.valid[None], hist, 0.0)

    def _spread(self, shift):
        """(B, D) shifts from the STAT_SPOTS spots' (B, S): affine in the spot's position
        (plate.cell_model), least squares over the spots measured."""
        if self._affine is None:
            return shift
        basis, coef_of = self._affine
        return (basis @ (coef_of @ shift.T)).T

    def _remember(self, rows, stats):
        if len(self._stats) + len(rows) > 64:  # bounded; what this call needs is in hand
            self._stats.clear()
        for row, keep, blur2, shift in zip(rows, *stats):
            self._stats[row.tobytes()] = (keep, blur2, shift)

    def _statistics_of(self, rows):
        """(keep, blur2, shift) stacked over rows, computed for rows not remembered (read from
        what was found and what was computed, not back from the memory, which may be cleared
        in between)."""
        keys = [r.tobytes() for r in rows]
        got = {k: self._stats[k] for k in keys if k in self._stats}
        new = {k: r for k, r in zip(keys, rows) if k not in got}
        if new:
            fresh_rows = np.array(list(new.values()))
            fresh = _plate_points(fresh_rows, self.lattice, self._stat_spots, self.obs.laser)[3]
            self._remember(fresh_rows, fresh)
            got.update((k, tuple(s[i] for s in fresh)) for i, k in enumerate(new))
        return tuple(np.stack([got[k][i] for k in keys]) for i in range(3))

    def columns(self, params) -> np.ndarray:
        """(K, D, n): each plate's histograms, shadowed by the others where they can be
        (model.shadow; one plate, or plates apart: each alone, as column_batch gives it)."""
        rows = np.reshape(params, (-1, plate.N_PARAMS))
        return self.column_batch(rows, occluders=self.occluders(rows))

    def occluders(self, params) -> list | None:
        """Per row of params (K, 6) the other rows that can shadow it (None where none can)."""
        rows = np.reshape(params, (-1, plate.N_PARAMS))
        if len(rows) < 2 or not self.shadows:  # shadows False: each plate alone, as before
            return None
        which = occluders_of(rows, self.obs.laser, self.obs.spots, self.lattice)
        return None if not any(len(w) for w in which) else [rows[w] for w in which]


def _statistics_spots(n_spots: int) -> np.ndarray:
    """Indices of the (at most plate.STAT_SPOTS) spots, spread over all, whose cell
    statistics a problem measures."""
    return unique_sorted(np.linspace(0, n_spots - 1, min(n_spots, plate.STAT_SPOTS))
                         .round()).astype(int)


def _affine_spread(obs, some, paired):
    """(basis, its pseudo-inverse on the statistics spots `some`) of the shift's affine fit,
    the same for every plate (plate.cell_statistics' basis: with each spot's own laser spot,
    its place too), or None where every spot is a statistics spot."""
    if len(some) == len(obs.spots):
        return None
    basis = np.hstack([np.ones((len(obs.spots), 1)), obs.spots - obs.spots.mean(axis=0)]
                      + ([obs.laser - obs.laser.mean(axis=0)] if paired else []))
    return basis, np.linalg.pinv(basis[some])


def _cells(rows, lattice):
    """Cell centres (B, C, 3), normals (B, 3), cell areas (B,), edge vectors (B, 3) x 2, in
    plate.plate_facets' order."""
    nu, nv = lattice
    x, w, h, yaw = rows[:, :3], rows[:, plate.WIDTH], rows[:, plate.HEIGHT], rows[:, plate.YAW]
    cos, sin = np.cos(yaw), np.sin(yaw)
    normal, across = np.zeros((len(rows), 3)), np.zeros((len(rows), 3))
    normal[:, 0], normal[:, 1] = cos, sin
    across[:, 0], across[:, 1] = -sin, cos
    u = ((np.arange(nu) + 0.5) / nu - 0.5)[None, :] * w[:, None]  # (B, nu)
    v = ((np.arange(nv) + 0.5) / nv - 0.5)[None, :] * h[:, None]  # (B, nv)
    centres = (x[:, None, None] + u[:, :, None, None] * across[:, None, None]
               + v[:, None, :, None] * plate.UP).reshape(len(rows), nu * nv, 3)
    eu, ev = across * (w / nu)[:, None], plate.UP[None] * (h / nv)[:, None]
    return centres, normal, w * h / (nu * nv), eu, ev


def _gauss_offsets(eu, ev):
    """(B, 4, 3): the 2 x 2 Gauss points' offsets from a cell's centre (plate._gauss_points'
    order)."""
    g = plate.GAUSS_2
    return (_SIGNS_U * g) * eu[:, None] + (_SIGNS_V * g) * ev[:, None]


# the Gauss points' signs along the cell's edges, in plate._gauss_points' order (4, 1)
_SIGNS_U = np.array([-1.0, -1.0, 1.0, 1.0])[:, None]
_SIGNS_V = np.array([-1.0, 1.0, -1.0, 1.0])[:, None]


def _plate_points(rows, lattice, spots, laser, stats=None):
    """Per plate what plate.cell_model gives the forward call: points (B, 4, C, 3), the
    plate's normal (B, 3) and cell area (B,), and its cell statistics (keep (B, C), blur^2
    (B,), shift (B, D)): computed here, or given (`stats`: other plates', one per row)."""
    centres, normal, area, eu, ev = _cells(rows, lattice)
    offsets = _gauss_offsets(eu, ev)[:, :, None, :]  # (B, 4, 1, 3)
    if stats is None:
        stats = _cell_statistics(centres, offsets, normal, area, spots, laser,
                                 plate.flat_share(lattice))
    points = centres[:, None] + stats[0][:, None, :, None] * offsets
    return points, normal, area, stats


def _cell_statistics(centres, offsets, normal, area, spots, laser, share=plate.BLUR_SHARE):
    """plate.cell_model's statistics of each cell's Gauss points: keep (B, C) (how far the
    points are pulled in), the blur^2 (B,) and the shift (B, S) at each of `spots` (the
    STAT_SPOTS the problem measures them at: HostProblem._spread carries them to all);
    share: the blur's share of the cells' mean variance (plate.flat_share)."""
    b, c = centres.shape[:2]
    full = (centres[:, None] + offsets).reshape(b, 4 * c, 3)  # the cells' Gauss points
    path, weight = _paths(full, normal, area / 4.0, spots, laser)
    path, weight = path.reshape(len(spots), b, 4, c), weight.reshape(len(spots), b, 4, c)
    wsum = weight.sum(axis=2)  # (S, B, C)
    safe = np.maximum(wsum, TINY)
    mean = (weight * path).sum(axis=2) / safe
    path -= mean[:, :, None]
    path *= path
    path *= weight
    var_sc = path.sum(axis=2) / safe
    centre = distance(centres, laser[None, None])[None] + distance(centres[None],
                                                                   spots[:, None, None])
    var_c = (var_sc * wsum).sum(axis=0) / np.maximum(wsum.sum(axis=0), TINY)  # (B, C)
    lit = wsum.sum(axis=0) > 0
    blur2 = share * np.where(lit, var_c, 0.0).sum(axis=1) / np.maximum(
        lit.sum(axis=1), 1)  # the lit cells' mean variance (0 where none is lit)
    keep = np.sqrt(np.clip(1.0 - blur2[:, None] / np.maximum(var_c, TINY), 0.0, 1.0))
    lost = (1.0 - keep ** 2)[None] * (mean - centre) * wsum  # (S, B, C)
    shift = (lost.sum(axis=2) / np.maximum(wsum.sum(axis=2), TINY)).T  # (B, S)
    return keep, blur2, shift


def _paths(points, normal, area, spots, laser, factor=None):
    """Hidden path r1 + r2 and weight per (detector, plate, point) (D, B, M): the forward
    twin's (ops.forward.facet_paths: four cosines, area / (r1^2 r2^2), 0 where the point faces
    away from O or the spot) for Lambertian upright plates, one normal per plate, without the
    twin's (D, F, 3) temporaries and in place (7x faster here). points (B, M, 3), each plate's
    in its plane; normal (B, 3), area (B,). factor: None, or the reflectance's direction
    factor as a function of n.l, n.v and l.v = -(v1 . v2) / (r1 r2) (model.estimator passes
    GGX's or Retroreflective's factor_of_cosines)."""
    px, py, pz = points[..., 0], points[..., 1], points[..., 2]  # (np.moveaxis: 11 us more)
    nx, ny = normal[:, 0], normal[:, 1]  # upright: no z component
    # The points lie in their plate's plane, so n . (P - O) = -r1 cos_b1 and n . (S - P) =
    # r2 cos_a2 are one number per plate (and spot): taken at the plate's first point. A plate
    # facing away from O or from a spot sends nothing there.
    p0 = points[:, 0]
    front_o = np.maximum(nx * (laser[0] - p0[:, 0]) + ny * (laser[1] - p0[:, 1]), 0.0)
    faces = np.maximum(nx * (spots[:, 0, None] - p0[:, 0]) + ny * (spots[:, 1, None] - p0[:, 1]),
                       0.0)  # (D, B)
    v1x, v1y, v1z = px - laser[0], py - laser[1], pz - laser[2]
    r1sq = v1x * v1x
    r1sq += v1y * v1y
    r1sq += v1z * v1z
    front = np.abs(v1y)  # -> cos_a1 cos_b1 area / r1^2
    front *= (front_o * area)[:, None]
    front /= r1sq
    front /= r1sq
    v2x, v2y, v2z, r2sq = spot_legs(px, py, pz, spots)
    if factor is not None:  # before v2y is overwritten
        dot = v1x * v2x + v1y * v2y + v1z * v2z
    weight = np.abs(v2y, out=v2y)  # -> cos_a2 cos_b2 / r2^2 x front
    weight *= faces[:, :, None]
    weight *= front
    weight /= r2sq
    weight /= r2sq
    if factor is not None:
        r1, r2 = np.sqrt(r1sq), np.sqrt(r2sq)
        weight *= factor(front_o[:, None] / r1, faces[:, :, None] / r2, -dot / (r1 * r2))
    path = np.sqrt(r2sq, out=r2sq)
    path += np.sqrt(r1sq)
    return path, weight
