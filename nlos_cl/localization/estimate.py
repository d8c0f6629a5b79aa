"""What estimators exchange: `Scored` (a scored grid and, for model fits, the histograms) and an
optional `Prior` in, `Estimate` / `Location` of `LocatedTarget`s out, and the `Estimator`
protocol between them, with the `Capabilities` an estimator declares so the Locator knows what
to hand it (a score map, its best cell's neighbourhood only, or just the paper's estimate)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from ..core.constants import LOG_FLOOR, PRODUCT_FLOOR
from ..core.errors import InputError
from ..core.grid import Grid


@dataclass(frozen=True)
class LocatedTarget:
    """One located target: centre (m, our frame) and what the estimator knows of it. `fit`: a
    model fit's typed result (nlos_cl.localization.fit_result.ModelFit), None for the paper's
    argmax; `details`: its JSON view (or an estimator's own dict, where it has no ModelFit)."""

    position: np.ndarray  # (3,)
    covariance: np.ndarray | None = None  # (3, 3) m^2, where the estimator provides one
    extent_m: np.ndarray | None = None  # size along its axes, where the estimator fits one
    details: dict = field(default_factory=dict)
    fit: object = None  # ModelFit | None

    def __post_init__(self):
        if self.fit is not None and not self.details:
            object.__setattr__(self, "details", self.fit.as_dict())


@dataclass(frozen=True)
class Estimate:
    """What an estimator returns: the targets (best first), the best cell and its score."""

    targets: list
    cell_position: np.ndarray
    score: float


@dataclass(frozen=True)
class Location:
    """Where the target is: `position` (m) is the first of `targets`. Positions, covariances,
    truth and cell are in the frame named by `frame` ("nlos_cl", ours, as every estimator gives
    them; a file's, after `in_frame`); `grid` is the search's, always ours."""

    position: np.ndarray  # (3,) metres
    cell_position: np.ndarray  # centre of the best cell
    score: float  # joint likelihood (or its log) at the best cell
    grid: Grid
    truth: np.ndarray | None = None
    score_map: np.ndarray | None = field(default=None, repr=False)  # (nz, ny, nx) if asked
    estimator: str = "paper"
    targets: list = field(default_factory=list)  # every LocatedTarget, best first
    # localization.detection.Detection, where the Locator tested the frame for any target
    # signal; with `detected` False, `targets` is empty and `position` the argmax of noise
    detection: Any = None
    frame: str = "nlos_cl"  # the frame of every coordinate above but `grid` (CaptureFrame.name)

    def in_frame(self, frame) -> "Location":
        """This location (ours) with its coordinates in `frame` (a CaptureFrame): positions,
        covariances, truth and best cell; the score map (along our grid) is left out, and each
        target's `fit` / `details` stay the estimator's record (ours). The identity frame
        returns it unchanged."""
        from ..io.json_format import covariance_in
        if self.frame != "nlos_cl":
            raise ValueError(f"in_frame: this location is already in the {self.frame} frame")
        if np.array_equal(np.asarray(frame.matrix), np.eye(3)) and not any(frame.origin):
            return self
        from dataclasses import replace
        targets = [replace(t, position=frame.from_internal(t.position),
                           covariance=covariance_in(t.covariance, frame)) for t in self.targets]
        return replace(self, position=frame.from_internal(self.position),
                       cell_position=frame.from_internal(self.cell_position),
                       truth=None if self.truth is None else frame.from_internal(self.truth),
                       score_map=None, targets=targets, frame=frame.name)

    @classmethod
    def of(cls, estimate: Estimate, grid: Grid, truth, score_map, estimator: str,
           detection=None) -> "Location":
        return cls(estimate.targets[0].position, estimate.cell_position, estimate.score, grid,
                   truth, score_map, estimator, list(estimate.targets), detection)

    @classmethod
    def undetected(cls, paper: Estimate, grid: Grid, truth, detection, estimator: str,
                   score_map=None) -> "Location":
        """No target signal in the frame: the argmax as `position`, no targets."""
        return cls(paper.targets[0].position, paper.cell_position, paper.score, grid, truth,
                   score_map, estimator, [], detection)

    @property
    def detected(self) -> bool:
        """False only where the frame was tested and holds no target signal."""
        return self.detection is None or bool(self.detection.detected)

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
    host_rows: object = None  # the filtered rows as the Locator read them to the host (its
    # detection), in their stored dtype, or None: read them from `signals` (for reading only;
    # a large record's are valid until the Locator's next call: locator.KEEP_ROWS_BYTES)


@dataclass(frozen=True)
class Capabilities:
    """What an estimator needs from the Locator. local: it reads only the best cell's 3 x 3 x 3
    neighbourhood of the score map (coarse-to-fine search may skip the rest); from_paper: it
    needs only the paper's estimate (`Scored.paper`), no score map at all (the Locator's fused
    search gives it in one read); is_paper: its answer *is* the paper's estimate (the Locator
    returns the fused search's estimate without calling it); needs_raw: it fits the unfiltered
    histograms (`Scored.raw`); paired: it locates layouts whose histograms each have their own
    laser spot (confocal and paired captures); warm_start: it starts from a `Prior` (the
    tracks' predicted targets, `estimate(scored, prior)`), so a Tracker warm-starts it."""

    local: bool = False
    from_paper: bool = False
    is_paper: bool = False
    needs_raw: bool = False
    paired: bool = False
    warm_start: bool = False


NO_CAPABILITIES = Capabilities()  # an estimator that declares none: it gets the whole map


def capabilities_of(estimator) -> Capabilities:
    return getattr(estimator, "capabilities", NO_CAPABILITIES)


# How a fit's warning that its residual still holds a return begins (model.policy.sanity's
# leftover_note builds it; localization.separate and the tracker's births read it). Here, in the
# answers' module, so that reading it imports no model.
LEFTOVER = "the data hold signal the fitted target(s) do not explain"


@dataclass(frozen=True)
class Prior:
    """Where a frame's targets are expected, to start a fit from (a tracker's prediction):
    `rows` (K, n) of the estimator's shape parameters (the model estimator: plate rows x, y, z,
    width, height, yaw), one per target. size, size_sd: None, or (K, 2) each, each target's
    width and height as known from elsewhere (e.g. the frames where nothing hid it) and their
    sd (inf: not known): the model estimator's warm fit starts a plate the others partly hide
    at that size and holds it there within size_sd, since there the data cannot tell a partly
    hidden plate from a smaller one (nlos_cl.localization.model.policy.warm.size_prior); its cold
    fallback ignores them. misfit: None, or the Birge ratio the estimator's cold fit of these
    targets last reached (the model's own floor on these data, e.g. a learned background's
    residue): a warm fit that misses the data by no more than that, within the noise's 99.9 %
    point, is kept, as the cold fit would land there too (model.policy.warm.warm_fit). shape:
    None (plates), or a closed family's name ('box', 'ellipsoid', 'cylinder', 'capsule': rows of
    its 7 parameters, x, y, z, width, height, depth, yaw), warm-fitted in that family (a tracked
    person's cylinder; plates among them at the family's least depth). measured: None, or the
    rows as last fitted, before a motion model moved them (tried where `rows` miss: a velocity
    learnt from a poor measurement or a turn sends a prediction out of the basin). late: the
    cold fit explained the data with late copies of the light (model.forward.late: an IRF
    tail, a person's broad body return), so the warm fit carries them too."""

    rows: np.ndarray
    size: np.ndarray | None = None
    size_sd: np.ndarray | None = None
    misfit: float | None = None
    shape: str | None = None
    measured: np.ndarray | None = None
    late: bool = False


class Estimator(Protocol):
    name: str

    @property
    def capabilities(self) -> Capabilities: ...

    def estimate(self, scored: Scored, prior: Prior | None = None) -> Estimate: ...


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
