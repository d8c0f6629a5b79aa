"""Closed shapes (box, ellipsoid, cylinder, capsule) evaluated on the host, a batch of rows
per call: the model of `likelihood.Problem(shape=...)`, whose `column` makes one forward launch per
lit face, in float64 NumPy and vectorised over every piece of every row of a Jacobian.

Why: a one-target fit that tries the closed shapes makes ~2,000 of their columns (44 LM
fits from their starts, cross-seeded and rounded refits, the depth profile). On a 6-spot
layout a column cost ~5 ms on PoCL: ~2.5 ms of launches and read-backs for a few thousand
point facets x 6 detectors x 85 bins (the arithmetic is microseconds), ~2.5 ms of cell
statistics on the host. One-target draws with a closed shape took 20 s a locate (median).

Same model as `Problem.column`: per piece (a box's face; a curved shape's whole surface) the
cells the laser lights and a spot sees (ellipsoid.lit_mask), their statistics
(plate.cell_statistics: pull-in, shared blur, shift per detector), the pulled-in Gauss points,
each piece its own pulse width; the bins integrated over their width by model.batch's
deposit and correlation (split error <= 2e-4 of the peak, as the kernel's).

A Jacobian's moved rows (`column_batch(rows, like)`) borrow the unmoved row's culling and cell
statistics, as model.batch.HostProblem's plates do: derivatives at frozen blur, shift and
pull-in (a cell that turns into or out of view is at zero weight there, so borrowing its
culling changes nothing to first order); residuals always use each row's own.
"""
from __future__ import annotations

import math
import time

import numpy as np

from ....core.allocator import keep_freed_memory
from ....core.constants import TINY
from ....core.geometry import Facets, spot_legs
from ....ops.forward import SUB_BINS_PER_SIGMA
from ..shapes import plate
from ..shapes.ellipsoid import culled, lit_mask
from .deposit import deposit_bins
from .likelihood import Problem
from .shadow import cell_size, occluders_of, plate_rows, visible

# point-detector pairs per NumPy pass (each temporary ~8 bytes a pair): bounds the memory
PAIRS_PER_PASS = 1_500_000
STATS_KEPT = 64  # rows whose culling and cell statistics are remembered (for `like`)


def shape_problem(problem, shape):
    """The closed shape's Problem for the data of plate problem `problem`: on the host where
    the estimator put it there (`problem.closed_on_host`, model.estimator), else the forward
    op on the device (one launch per lit face and column)."""
    if problem.closed_on_host:
        return HostShapeProblem(problem.obs, shape, problem.lattice, problem.backend,
                                problem.reflectance)
    return Problem(problem.obs, problem.backend, problem.lattice, shape=shape,
                   reflectance=problem.reflectance)


def host_can(reflectance) -> bool:
    """Whether the host's models know this reflectance (None: Lambertian; a factor of n.l,
    n.v and l.v: GGX, Retroreflective)."""
    return reflectance is None or hasattr(reflectance, "factor_of_cosines")


class HostShapeProblem(Problem):
    """A `Problem` for one closed shape (`shape`: model.box, .ellipsoid, .cylinder or .capsule:
    their `pieces`) evaluated on the host. reflectance: None (Lambertian) or one with
    factor_of_cosines (GGX, Retroreflective), as model.batch.HostProblem; the laser one spot (3,)
    or one per detector (D, 3)."""

    batched = True  # column_batch: one host call (or one launch) for all rows

    def __init__(self, obs, shape, lattice=(16, 24), backend=None, reflectance=None):
        super().__init__(obs, backend, lattice, shape=shape, reflectance=reflectance)
        keep_freed_memory()  # core.allocator
        if not host_can(reflectance):
            raise ValueError("reflectance: the host model takes a factor of n.l, n.v and l.v "
                             "(GGX, Retroreflective); use likelihood.Problem for this one")
        self._factor = None if reflectance is None else reflectance.factor_of_cosines
        floor = math.sqrt(max(obs.sigma0_m ** 2 - obs.box_excess_m2, TINY))
        self.os = max(1, math.ceil(float(np.max(obs.dpath)) * SUB_BINS_PER_SIGMA / floor))
        self._stats = {}  # row bytes -> per piece (mask, keep, blur2, shift) (`_statistics`)
        self._near = {}  # row bytes -> per piece its Gauss points (`_points`)
        self._taps = {}
        # the closed targets' mutual shadows (`occluders`), as HostProblem's plates: one laser
        self.shadows = np.asarray(obs.laser).ndim == 1

    def column(self, p) -> np.ndarray:
        return self.column_batch(np.asarray(p, float)[None])[0]

    def column_batch(self, rows, like=None, occluders=None) -> np.ndarray:
        """(B, D, n) unit-amplitude histograms of rows (B, 7); like: None, or (B, 7) rows
        whose culling and cell statistics each row borrows (a Jacobian's). occluders: None,
        or per row the (K', 7) closed rows that can shadow it (`occluders`): their front
        faces block its points' rays as plates do (model.shadow)."""
        t = time.perf_counter()
        rows = np.atleast_2d(np.asarray(rows, np.float64))
        obs = self.obs
        pieces = []  # (row index, points, normals, areas, blur2, shift, (fronts, cell) or None)
        for i, row in enumerate(rows):
            source = row if like is None else like[i]  # whose culling and statistics
            shade = self._shading(row, None if occluders is None else occluders[i])
            for pts, (_, _, blur2, shift) in zip(self._points(row, source),
                                                 self._statistics(source)):
                if pts is not None:
                    pieces.append((i, pts.centres, pts.normals, pts.areas, blur2, shift, shade))
        out = np.zeros((len(rows),) + obs.y.shape)
        for group in _groups(pieces, len(obs.spots)):
            hist = self._evaluate(group)
            for (i, *_), h in zip(group, hist):
                out[i] += h
        self.calls += len(rows)
        self.model_s += time.perf_counter() - t
        return np.where(obs.valid[None], out, 0.0)

    def columns(self, params) -> np.ndarray:
        """(K, D, n): each target's histograms, shadowed by the others' front faces where
        they can be (`occluders`), as model.batch.HostProblem's plates."""
        rows = np.reshape(params, (-1, self.shape.N_PARAMS))
        return self.column_batch(rows, occluders=self.occluders(rows))

    def occluders(self, params) -> list | None:
        """Per row of params (K, 7) the other rows whose front faces can shadow it (None where
        none can): model.shadow's bounding test on the front faces (shadow.plate_rows). Not
        for paired lasers (the shadow model knows one)."""
        rows = np.reshape(params, (-1, self.shape.N_PARAMS))
        if len(rows) < 2 or not self.shadows:
            return None
        which = occluders_of(plate_rows(rows), self.obs.laser, self.obs.spots, self.lattice)
        return None if not any(len(w) for w in which) else [rows[w] for w in which]

    def _shading(self, row, occluders):
        """(front-face plate rows of `occluders`, the ramp's cell on `row`) or None."""
        if occluders is None or not len(occluders):
            return None
        front = plate_rows(np.atleast_2d(row))
        return plate_rows(occluders), float(cell_size(front, self.lattice)[0])

    def _points(self, row, source) -> list:
        """Per piece of `row` its pulled-in Gauss points on the cells `source` lights and a
        spot sees, with source's statistics (None: no cell). A row that moves only the
        centre from a source whose points are in hand (a Jacobian's x, y, z columns: 3 of a
        closed shape's 7) is those points moved: every shape is built around its centre
        (translating it moves its cells, normals and edges stay), so its cells, culling and
        Gauss points are not built again (the same points to the last bits of the sum)."""
        near = self._near.get(source.tobytes())
        if near is not None and np.array_equal(row[3:], source[3:]):
            delta = row[:3] - source[:3]
            return [None if p is None else Facets(p.centres + delta, p.normals, p.areas)
                    for p in near]
        own = self.shape.pieces(row, self.lattice)
        mine = np.array_equal(source, row)
        out = [None if not mask.any() else
               plate._gauss_points(*culled(cells, edges, mask), keep)
               for (cells, edges, _), (mask, keep, _, _) in
               zip(own, self._statistics(source, own if mine else None))]
        if mine:  # bounded as the statistics
            if len(self._near) >= STATS_KEPT:
                self._near.clear()
            self._near[row.tobytes()] = out
        return out

    def _statistics(self, row, pieces=None):
        """Per piece of closed shape `row`: the lit-and-seen mask of its cells and their
        statistics on the masked cells (keep, blur2, shift); remembered by the row."""
        key = row.tobytes()
        got = self._stats.get(key)
        if got is not None:
            return got
        obs = self.obs
        pieces = self.shape.pieces(row, self.lattice) if pieces is None else pieces
        got = []
        for cells, edges, share in pieces:
            mask = lit_mask(cells.centres, cells.normals, obs.spots, obs.laser)
            if mask.any():
                stats = plate.cell_statistics(*culled(cells, edges, mask), obs.spots, obs.laser,
                                              share)
            else:
                stats = (np.zeros(0), 0.0, np.zeros(len(obs.spots)))
            got.append((mask, *stats))
        if len(self._stats) >= STATS_KEPT:  # bounded; what this call needs is in hand
            self._stats.clear()
        self._stats[key] = got
        return got

    def _evaluate(self, group) -> np.ndarray:
        """(G, D, n): the histograms of a group of pieces, their points one after another (each
        piece's own: no padding to the largest, whose zero-area points were a quarter of a
        box's arithmetic; the deposit's sums are the same, bit for bit: deposit.split)."""
        obs = self.obs
        sizes = [len(p[1]) for p in group]
        points = np.concatenate([p[1] for p in group])[None]  # (1, M, 3)
        normals = np.concatenate([p[2] for p in group])[None]
        areas = np.concatenate([p[3] for p in group])[None]
        blur2 = np.array([p[4] for p in group])
        edge0 = obs.edge0[None] - np.stack([p[5] for p in group])  # (G, D): shifted
        sigma = np.sqrt(obs.sigma0_m ** 2 + blur2 - obs.box_excess_m2)
        laser = np.asarray(obs.laser, float)
        out = np.empty((len(group),) + obs.y.shape)
        # detectors a pass: as many as when pieces were padded to the largest (the same
        # passes, so the same windows: split's pad is a pass's)
        step = max(1, PAIRS_PER_PASS // (len(group) * max(sizes)))
        for d in range(0, len(obs.spots), step):
            part = slice(d, d + step)
            path, weight = point_paths(points, normals, areas, obs.spots[part],
                                       laser[part] if laser.ndim == 2 else laser, self._factor)
            _shade(weight[:, 0], points[0], group, sizes, laser, obs.spots[part])
            out[:, part] = deposit_bins(path[:, 0], weight[:, 0], edge0[:, part],
                                        obs.dpath[part], sigma, obs.n, self.os, self._taps,
                                        np.array(sizes))
        return out


def _shade(weight, points, group, sizes, laser, spots) -> None:
    """weight (D, M) of a group's points (M, 3), piece after piece (`sizes`), times each
    shaded piece's share past its occluders' front faces (model.shadow.visible), in place."""
    at = 0
    for piece, size in zip(group, sizes):
        if piece[6] is not None:
            fronts, cell = piece[6]
            weight[:, at:at + size] *= visible(points[at:at + size], laser, spots, fronts, cell)
        at += size


def _groups(pieces, n_det):
    """The pieces in consecutive groups of at most PAIRS_PER_PASS (point, detector) pairs
    (padded to the group's largest piece); a piece larger alone is a group of its own, which
    `_evaluate` splits over the detectors."""
    group, largest = [], 0
    for piece in pieces:
        size = max(largest, len(piece[1]))
        if group and (len(group) + 1) * size * n_det > PAIRS_PER_PASS:
            yield group
            group, size = [], len(piece[1])
        group.append(piece)
        largest = size
    if group:
        yield group


def point_paths(points, normals, areas, spots, laser, factor=None):
    """Hidden path r1 + r2 and weight per (detector, piece, point) (D, G, M): the forward
    twin's (ops.forward.facet_paths: four cosines, area / (r1^2 r2^2), 0 where the point faces
    away from the laser spot or the detector spot) with a normal per point, component by
    component and in place (no (D, G, M, 3) temporaries). points, normals (G, M, 3), areas
    (G, M); laser (3,) or (D, 3) (each detector its own); factor: the reflectance's factor of
    n.l, n.v and l.v, or None. (batch._paths is its special case for upright plates, one normal and one
    laser spot: the facing factors one number per plate and spot, 10-40 % faster on the
    plates' problems, within 1e-15 of this.)"""
    laser = np.asarray(laser, float)
    lasers = laser.reshape(-1, 1, 1, 3)  # (1 or D, 1, 1, 3)
    px, py, pz = (points[None, ..., k] for k in range(3))
    nx, ny, nz = (normals[None, ..., k] for k in range(3))
    v1x, v1y, v1z = px - lasers[..., 0], py - lasers[..., 1], pz - lasers[..., 2]
    r1sq = v1x * v1x + v1y * v1y + v1z * v1z
    # cos_a1 cos_b1 area / r1^2 = |v1y| max(-n.v1, 0) area / r1^4
    front = np.maximum(-(nx * v1x + ny * v1y + nz * v1z), 0.0)
    front *= np.abs(v1y)
    front *= areas[None]
    front /= r1sq
    front /= r1sq
    v2x, v2y, v2z, r2sq = spot_legs(px, py, pz, spots)
    weight = nx * v2x  # -> max(n.v2, 0) |v2y| / r2^4 x front
    weight += ny * v2y
    weight += nz * v2z
    np.maximum(weight, 0.0, out=weight)
    weight *= np.abs(v2y)
    weight *= front
    weight /= r2sq
    weight /= r2sq
    if factor is not None:
        r1, r2 = np.sqrt(r1sq), np.sqrt(r2sq)
        dot = v1x * v2x + v1y * v2y + v1z * v2z
        cos_l = -(nx * v1x + ny * v1y + nz * v1z) / r1
        cos_v = (nx * v2x + ny * v2y + nz * v2z) / r2
        weight *= factor(cos_l, cos_v, -dot / (r1 * r2))
    path = np.sqrt(r2sq, out=r2sq)
    path += np.sqrt(r1sq)
    return path, weight
