"""Estimators: from a scored grid (and, for model fits, the histograms) to a `Location`.

The `Locator` plan scores the grid; an estimator turns that into positions. The paper's
estimator (`PaperArgmax`) is the first: the argmax of the joint likelihood, refined below the
cell size by a parabola per axis. Others plug in through the same `estimate(scored)` call. The
default (`as_estimator(None)`) is the model fit (nlos_cl.model, loaded on first use).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from .constants import LOG_FLOOR, PRODUCT_FLOOR
from .errors import InputError
from .grid import Grid
from .ops.argmax_patch import neighbourhood


@dataclass(frozen=True)
class LocatedTarget:
    """One located target: centre (m, our frame) and what the estimator knows of it."""

    position: np.ndarray  # (3,)
    covariance: np.ndarray | None = None  # (3, 3) m^2, where the estimator provides one
    extent_m: np.ndarray | None = None  # size along its axes, where the estimator fits one
    details: dict = field(default_factory=dict)  # estimator-specific (fit parameters, ...)


@dataclass(frozen=True)
class Estimate:
    """What an estimator returns: the targets (best first), the best cell and its score."""

    targets: list
    cell_position: np.ndarray
    score: float


@dataclass(frozen=True)
class Location:
    """Where the target is: `position` (m, our frame) is the first of `targets`."""

    position: np.ndarray  # (3,) metres
    cell_position: np.ndarray  # centre of the best cell
    score: float  # joint likelihood (or its log) at the best cell
    grid: Grid
    truth: np.ndarray | None = None
    score_map: np.ndarray | None = field(default=None, repr=False)  # (nz, ny, nx) if asked
    estimator: str = "paper"
    targets: list = field(default_factory=list)  # every LocatedTarget, best first

    @classmethod
    def of(cls, estimate: Estimate, grid: Grid, truth, score_map, estimator: str) -> "Location":
        return cls(estimate.targets[0].position, estimate.cell_position, estimate.score, grid,
                   truth, score_map, estimator, list(estimate.targets))

    @property
    def covariance(self) -> np.ndarray | None:
        """(3, 3) m^2 of the first target, where the estimator provides one."""
        return self.targets[0].covariance if self.targets else None

    @property
    def error_m(self) -> float | None:
        if self.truth is None:
            return None
        return float(np.linalg.norm(self.position - self.truth))


@dataclass(frozen=True)
class Scored:
    """What a Locator hands its estimator for one frame."""

    backend: object
    scores: object  # the score map on the backend
    grid: Grid
    log_mode: bool
    n_detectors: int
    signals: object  # the filtered Signals that were scored
    raw: object = None  # the unfiltered Signals, where the caller passed them (model fits)
    paper: object = None  # the paper's Estimate, where the Locator's fused search made it
    # (for estimators with `needs_only_paper_estimate`: then `scores` is None)


class Estimator(Protocol):
    name: str

    def estimate(self, scored: Scored) -> Estimate: ...


class PaperArgmax:
    """The paper's estimator (Section 3.2): the cell of maximum joint likelihood, refined with
    a parabola per axis through the log-score of the best cell and its two neighbours."""

    name = "paper"

    def estimate(self, scored: Scored):
        be, grid = scored.backend, scored.grid
        flat, best = be.call("argmax", scored.scores)
        check_signal(flat >= 0, best, scored.log_mode, scored.n_detectors)
        nx, ny, _ = grid.shape
        iz, rem = divmod(flat, nx * ny)
        iy, ix = divmod(rem, nx)
        patch = neighbourhood(lambda z, a, b: be.read_rows(scored.scores, z, a, b), grid.shape,
                              (ix, iy, iz))
        return self.from_patch((ix, iy, iz), best, patch, grid, scored.log_mode,
                               scored.n_detectors)

    def from_patch(self, index, best, patch, grid: Grid, log_mode: bool, n_detectors: int):
        """The estimate from the best cell's index (ix, iy, iz) on `grid` (None: no cell), its
        score and the 3 x 3 x 3 scores around it (NaN outside the grid), as the device's fused
        searches return them (nlos_cl/ops/fused_search.py, argmax_patch.py): no launch."""
        check_signal(index is not None, best, log_mode, n_detectors)
        cell = np.array([o + s * i for o, s, i in zip(grid.origin, grid.step, index)])
        logp = patch if log_mode else np.log(np.maximum(patch, 1e-300))
        position = cell + parabolic_offsets(logp) * np.asarray(grid.step)
        return Estimate([LocatedTarget(position)], cell, best)


def check_signal(found: bool, best: float, log_mode: bool, n_detectors: int) -> None:
    """Raise unless a cell was found with a likelihood above the numerical zero: every detector
    at its log floor, or a product beyond float32's range (the float64 twin would otherwise
    "locate" on 1e-67)."""
    floor = n_detectors * math.log(LOG_FLOOR) if log_mode else PRODUCT_FLOOR
    if not found or not best > floor:
        raise InputError("grid: no cell has a non-zero likelihood from every detector: the "
                         "signals do not reach the grid. Fix: check that the grid covers "
                         "the hidden area the time axis sees, and the calibration; with many "
                         "detectors use log_mode=True")

def parabolic_offsets(logp):
    """Per axis (x, y, z), the vertex of the parabola through (-1, 0, +1) cells, in cells."""
    offsets = np.zeros(3)
    lines = (logp[1, 1, :], logp[1, :, 1], logp[:, 1, 1])
    for axis, (m, c, p) in enumerate(lines):
        if not (np.isfinite(m) and np.isfinite(c) and np.isfinite(p)):
            continue  # the best cell is on the grid's edge (or a neighbour is -inf)
        curvature = m - 2 * c + p
        if curvature < 0:
            offsets[axis] = float(np.clip(0.5 * (m - p) / curvature, -0.5, 0.5))
    return offsets


ESTIMATORS = {"paper": PaperArgmax,
              # lazy: nlos_cl.model (SciPy) loads only when the model estimator is asked for
              "model": lambda: __import__("nlos_cl.model", fromlist=["_"]).ModelEstimator()}


# The default (issue 11): the most accurate estimator within the time budget, the model fit.
DEFAULT_ESTIMATOR = "model"


def as_estimator(value):
    """A name ('paper', 'model'), an object with estimate(scored), or None: the default."""
    if value is None:
        value = DEFAULT_ESTIMATOR
    if isinstance(value, str):
        if value not in ESTIMATORS:
            raise InputError(f"estimator: unknown name {value!r}. Fix: pass one of "
                             f"{sorted(ESTIMATORS)} or an object with estimate(scored)")
        return ESTIMATORS[value]()
    if not hasattr(value, "estimate"):
        raise InputError(f"estimator: expected a name or an object with estimate(scored), got "
                         f"{type(value).__name__}. Fix: pass e.g. 'paper'")
    return value
