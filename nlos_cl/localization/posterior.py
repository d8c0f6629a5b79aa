"""The paper's joint likelihood read as a posterior over the search region: its mean and
covariance (estimator 'mean'), and the argmax with the likelihood's spread about it as its
covariance (`ArgmaxSpread`: what locate_capture's 'paper' answers carry).

The paper's estimate is the likelihood's argmax. Where the likelihood is broad and flat-topped
(few detectors, coarse bins: the consumer sensor's 16 zones of 250 ps bins, whose likelihood
stays within 10 of its maximum's log over ~10^5 cells of 1.65 cm), the argmax wanders over
that top from frame to frame. The likelihood's mean under a flat prior over the region averages
over it. Measured on the consumer sensor's walk (475 frames; robust sd of second differences
per axis; distance to the authors' particle filter in the top view, median):

                       scatter per axis (m)    to the particle filter
    paper's argmax     0.171 0.183 0.123       0.167 m
    likelihood mean    0.098 0.098 0.061       0.118 m

The mean is read as it is (the log score taken as a log-likelihood; a tempered one, score / T,
moves it toward the region's centre: T = 10 put it 0.27 m from the filter), its spread as the
covariance (plus each cell's own (stride step)^2 / 12).

The map is scored twice, both bounded by the region's own cell count: on a sub-grid, every
STRIDE-th cell along each axis with more than one cell (8x fewer cells for a volume), then, where
it holds fewer cells than that sub-grid, at full resolution on the box of BOX_SD sds around the
first pass's mean (a likelihood a few cells wide, which the sub-grid would sample too coarsely).
On the walk every 2nd cell alone gave means 0.5 mm from every cell's (median; 90th percentile
4.8 mm, worst 64 mm) against their 0.1 m scatter. Cells whose log score lies more than
LOG_SPAN below the maximum weigh under e^-LOG_SPAN and are skipped.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..core.constants import LOG_FLOOR
from ..core.grid import Grid
from .estimate import Capabilities, Estimate, LocatedTarget
from .paper import PaperArgmax

STRIDE = 2
LOG_SPAN = 30.0
BOX_SD = 5.0  # the full-resolution pass's half-size, in the first pass's sds


class PosteriorMean:
    """The mean and covariance of the paper's joint likelihood over the search region (the
    module docstring); the Estimate's cell and score stay the paper's argmax's."""

    name = "mean"
    # the paper's argmax from the fused search (one read), the sub-grid's map scored here
    capabilities = Capabilities(from_paper=True, paired=True)

    def __init__(self, stride: int = STRIDE):
        self.stride = int(stride)
        self._plan = None  # (grid, sub-grid, its score buffer), reused frame after frame

    def estimate(self, scored, prior=None) -> Estimate:
        """The likelihood's mean and covariance on `scored.signals` (a prior changes nothing)."""
        paper = scored.paper if scored.paper is not None else PaperArgmax().estimate(scored)
        sig, be, grid = scored.signals, scored.backend, scored.grid
        sub = self._sub_grid(grid)
        stats = be.call("row_stats", sig.handle)
        scores = self._score(sig, stats, sub, scored.log_mode, self._plan[2])
        self._plan = self._plan[:2] + (scores,)
        mean, cov = likelihood_moments(be.to_numpy(scores), sub, scored.log_mode)
        if mean is None:  # no cell of the sub-grid above zero: the argmax's cell alone
            return paper
        box = box_around(grid, mean, np.sqrt(np.diag(cov)) * BOX_SD)
        if np.prod(box.shape) < np.prod(sub.shape):
            fine = self._score(sig, stats, box, scored.log_mode, None)
            fine_mean, fine_cov = likelihood_moments(be.to_numpy(fine), box, scored.log_mode)
            if fine_mean is not None:  # (a box of zeros keeps the sub-grid's answer)
                mean, cov = fine_mean, fine_cov
        target = LocatedTarget(mean, covariance=cov,
                               details={"argmax_m": [float(v) for v in paper.targets[0].position]})
        return Estimate([target], paper.cell_position, paper.score)

    @staticmethod
    def _score(sig, stats, grid: Grid, log_mode: bool, out):
        layout, axis = sig.layout, sig.layout.path_axis()
        return sig.backend.call("ellipse_score", sig.handle, stats, layout.detector_spots,
                                layout.laser_spot, axis.centre0_m, 1.0 / axis.step_m, grid,
                                log_mode, LOG_FLOOR, out=out)

    def _sub_grid(self, grid: Grid) -> Grid:
        if self._plan is None or self._plan[0] != grid:
            self._plan = (grid, strided(grid, self.stride), None)
        return self._plan[1]


def strided(grid: Grid, stride: int) -> Grid:
    """Every `stride`-th cell of `grid` along each axis with more than one cell, from its first."""
    step = [s * stride if n > 1 else s for s, n in zip(grid.step, grid.shape)]
    shape = [(n - 1) // stride + 1 if n > 1 else 1 for n in grid.shape]
    return Grid(grid.origin, tuple(step), tuple(shape))


def box_around(grid: Grid, centre, half) -> Grid:
    """`grid`'s cells within `half` (3,) of `centre` (at least the cells either side), the
    count along each axis rounded up to a power of two (or the grid's own count where that is
    fewer) and the box moved inside the grid. Why the rounding: PoCL builds a kernel anew for
    each local size it picks, and picks it from the global size, so boxes of every shape would
    each cost a build (~1 s) on a cold kernel cache and a file in it; snapped, the shapes are a
    few (the consumer walk's 475 frames: 6 builds of ellipse_score in all, the Locator's own
    among them)."""
    o, st, n = (np.asarray(v, dtype=np.float64) for v in (grid.origin, grid.step, grid.shape))
    half = np.maximum(half, st)
    lo = np.ceil((centre - half - o) / st)
    hi = np.floor((centre + half - o) / st)
    want = np.maximum(hi - lo + 1, 1)
    size = np.minimum(2.0 ** np.ceil(np.log2(want)), n)
    first = np.clip(lo - np.floor((size - want) / 2), 0, n - size)
    return Grid(tuple(o + first * st), tuple(st), tuple(int(v) for v in size))


def likelihood_moments(scores: np.ndarray, grid: Grid, log_mode: bool):
    """(mean (3,), covariance (3, 3)) of the likelihood `scores` ((nz, ny, nx): log scores in
    log mode, else the product) normalised over `grid`'s cells, each cell's own variance
    step^2 / 12 added; (None, None) where no cell holds a positive likelihood.

    From the weights' three 2-D marginals: every moment up to the second is a sum over one of
    them (the walk's 432 k cells: ~5 ms, against ~17 for the cells' coordinates listed)."""
    s = np.asarray(scores, dtype=np.float32).reshape(grid.shape[::-1])
    top = float(np.max(s)) if s.size else float("nan")
    if not np.isfinite(top) or (not log_mode and not top > 0):
        return None, None
    with np.errstate(under="ignore", invalid="ignore"):
        w = np.exp(s - np.float32(top)) if log_mode else s / np.float32(top)
    # below LOG_SPAN under the maximum (and NaN): nothing
    w = np.where(w >= np.float32(np.exp(-LOG_SPAN)), w, np.float32(0))
    w_yx, w_zx, w_zy = (w.sum(axis=a, dtype=np.float64) for a in (0, 1, 2))
    total = w_yx.sum()
    o, st = np.asarray(grid.origin), np.asarray(grid.step)
    x, y, z = (o[i] + st[i] * np.arange(n) for i, n in enumerate(grid.shape))
    px, py, pz = w_yx.sum(axis=0) / total, w_yx.sum(axis=1) / total, w_zy.sum(axis=1) / total
    mean = np.array([px @ x, py @ y, pz @ z])
    dx, dy, dz = x - mean[0], y - mean[1], z - mean[2]
    cxy = dy @ w_yx @ dx / total
    cxz = dz @ w_zx @ dx / total
    cyz = dz @ w_zy @ dy / total
    cov = np.array([[px @ dx ** 2, cxy, cxz], [cxy, py @ dy ** 2, cyz], [cxz, cyz, pz @ dz ** 2]])
    cov += np.diag(np.where(np.asarray(grid.shape) > 1, st ** 2 / 12, 0.0))
    return mean, cov


class ArgmaxSpread:
    """The paper's argmax (its answer unchanged) with a covariance: the paper likelihood's
    second moment about the argmax over the region (posterior.PosteriorMean's mean and
    covariance C, plus d d^T for the argmax's offset d from that mean), so a paired or confocal
    answer carries an uncertainty too. Its name stays 'paper'."""

    name = "paper"
    capabilities = Capabilities(from_paper=True, paired=True)

    def __init__(self):
        self._mean = PosteriorMean()

    def estimate(self, scored, prior=None):
        paper = scored.paper if scored.paper is not None else PaperArgmax().estimate(scored)
        target = self._mean.estimate(replace(scored, paper=paper)).targets[0]
        if target.covariance is None:  # no cell above zero: the argmax alone
            return paper
        argmax = paper.targets[0].position
        d = np.asarray(argmax) - target.position
        spread = LocatedTarget(argmax, covariance=target.covariance + np.outer(d, d),
                               details={"covariance": "the paper likelihood's spread about "
                                        "the argmax"})
        return Estimate([spread], paper.cell_position, paper.score)
