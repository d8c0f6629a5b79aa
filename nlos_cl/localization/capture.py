"""Locate a capture: what `nlos-cl locate` does, as one library call.

`locate_capture(path_or_sets)` reads a y-tal capture (or takes HistogramSets already read),
subtracts a background and applies a calibration where given, and per laser point: chooses the
search region (nlos_cl.localization.region: derived from the capture, or ranges along the
file's own axes), filters, searches coarse -> zoom -> fine where the derived region had to be
coarsened, and runs the estimator on the final grid. The answer is a `CaptureLocation`: per
laser point the position in the file's frame and in ours, covariances, the grids and the
warnings; `as_json()` is the CLI's --json object.
"""
from __future__ import annotations

import math
import warnings as pywarnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.errors import InputError, require
from ..core.geometry import farthest_points
from ..core.grid import Grid
from ..core.histograms import HistogramSet
from ..core.tuning import SEARCH_DETECTORS, auto_log_mode
from ..io.json_format import covariance_in, covariance_json, rounded, vector_json
from ..io.ytal.frames import INTERNAL, CaptureFrame
from ..ops.gauss_filter import filter_window
from .api import gauss_filter, locate
from .estimate import Location, capabilities_of
from .estimators import choose_estimator
from .paper import PaperArgmax
from .posterior import ArgmaxSpread
from .region import default_region, on_region_edge, region_step, zoom_region
from .separate import one_or_more
from .shadow import shadows

REGION_NAMES = ("region", "step_m")  # how errors name the region options (a CLI: its flags)


def search_region(histograms: HistogramSet, frame: CaptureFrame = INTERNAL, region=None,
                  step_m: float | None = None, h_s: float | None = None, *,
                  names=REGION_NAMES, reach_from=None) -> tuple[Grid, bool]:
    """(grid in our frame, was it derived): `region` None derives it (default_region, as far as
    the signal of `reach_from`, default the histograms, reaches); three (low, high) ranges are
    along `frame`'s axes, at `step_m` (default: region_step); a Grid is ours, used as given."""
    if region is None:
        return default_region(histograms, h_s, reach_from=reach_from), True
    if isinstance(region, Grid):
        return region, False
    try:
        ranges = np.asarray(region, dtype=np.float64)
    except (TypeError, ValueError):
        ranges = np.zeros(0)
    require(ranges.shape == (3, 2), names[0], f"expected three (low, high) ranges along the "
            f"file's axes {frame.axes}, got {region!r}", "pass e.g. ((-5, -3), (0, 0), (1, 3))")
    step = region_step(histograms, h_s) if step_m is None else step_m
    grid = frame.grid(ranges, step)
    from ..core.limits import memory_limit
    need, limit = 4 * grid.n_cells, memory_limit()
    if need > limit:
        raise InputError(f"{names[0]}: {grid.n_cells:.3g} cells at a {step:g} m step need "
                         f"{need / 2**30:.1f} GiB for the score map, more than the "
                         f"{limit / 2**30:.1f} GiB allowed (half the memory available). "
                         f"Fix: a smaller region or a larger {names[1]}")
    return grid, False


@dataclass(frozen=True)
class PointLocation:
    """One laser point's answer, in the capture's frame (`frame`): `location` (positions,
    covariances, truth), `position`, `positions`, `covariances`. `internal` is the same answer
    in ours, as the estimators gave it; `laser_spot` and the grids are ours too (`frame.ranges`
    gives a grid along the file's axes)."""

    laser_point: int
    laser_spot: np.ndarray  # ours
    internal: Location  # ours
    grid: Grid  # the final search grid (the zoom, where the region was coarsened)
    region: Grid  # the search region
    log_mode: bool
    frame: CaptureFrame
    warnings: tuple = ()
    processing: dict | None = None  # what measured-data processing found and did, per step

    @property
    def location(self) -> Location:
        """The answer in the capture's frame (Location.in_frame: no score map there)."""
        return self.internal.in_frame(self.frame)

    @property
    def position(self) -> np.ndarray:
        return self.frame.from_internal(self.internal.position)

    @property
    def positions(self) -> list:
        """Every target's position, best first (file frame)."""
        return [self.frame.from_internal(t.position) for t in self.internal.targets]

    @property
    def covariances(self) -> list:
        """Every target's covariance (file frame, m^2; None where the estimator gives none)."""
        return [covariance_in(t.covariance, self.frame) for t in self.internal.targets]

    @property
    def zoomed(self) -> bool:
        return self.grid is not self.region

    @property
    def on_edge(self) -> bool:
        """The answer lies on the region's edge: the target may be outside it."""
        return on_region_edge(self.internal.position, self.region)

    def as_json(self) -> dict:
        """The CLI's per-laser-point object (file frame)."""
        loc, frame = self.internal, self.frame
        targets = [{"position": vector_json(t.position, frame),
                    "covariance": covariance_json(t.covariance, frame),
                    "extent_m": None if t.extent_m is None else rounded(t.extent_m)}
                   for t in loc.targets]
        return {"laser_point": self.laser_point,
                "laser_spot": (vector_json(self.laser_spot, frame) if np.ndim(self.laser_spot) == 1
                               else "paired: one per histogram (the capture's laser grid)"),
                "detected": loc.detected, "detection": loc.detection and loc.detection.as_dict(),
                "position": targets[0]["position"] if targets else None, "targets": targets,
                "truth": None if loc.truth is None else vector_json(loc.truth, frame),
                "argmax_cell": vector_json(loc.cell_position, frame),
                "error_m": None if loc.error_m is None else round(loc.error_m, 5),
                "estimator": loc.estimator, "log_mode": self.log_mode,
                "region": {"ranges_m": [list(r) for r in frame.ranges(self.grid)],
                           "step_m": min(self.grid.step), "cells": self.grid.n_cells},
                "processing": self.processing, "warnings": list(self.warnings),
                "shadowed": [s.as_json(frame, self.region) for s in
                             shadows(loc.targets, self.laser_spot)]}


@dataclass(frozen=True)
class CaptureLocation:
    """A capture's answer: one PointLocation per laser point (`points`), and what applied to
    all of them."""

    points: tuple
    frame: CaptureFrame
    source: str | None  # the file, where one was read
    device: str
    h_s: float
    calibration: object = None  # the PathCalibration applied, if any

    @property
    def position(self) -> np.ndarray:
        """The first laser point's position (file frame)."""
        return self.points[0].position

    def as_json(self, entries: list | None = None) -> dict:
        """The CLI's --json object; `entries`: the per-laser-point objects, where the caller
        added to them (default: each point's as_json())."""
        entries = [p.as_json() for p in self.points] if entries is None else entries
        cal = self.calibration
        return {"file": self.source, "frame": self.frame.as_json(), "device": self.device,
                "h_s": self.h_s, "calibration": None if cal is None else
                {"a_m_per_s": cal.a_m_per_s, "b_m": float(cal.b_m[0])},
                **(entries[0] if len(entries) == 1 else {"per_laser_point": entries})}


def _sets(capture, frame):
    """(sets, frame, source) from a path, a HistogramSet or a sequence of them."""
    if isinstance(capture, (str, Path)):
        from ..io.ytal.capture import read_capture_with_frame
        sets, file_frame = read_capture_with_frame(capture)
        return sets, file_frame if frame is None else frame, str(capture)
    sets = [capture] if isinstance(capture, HistogramSet) else \
        list(capture) if isinstance(capture, (list, tuple)) else []
    require(bool(sets) and all(isinstance(h, HistogramSet) for h in sets), "capture",
            f"expected a capture's path or HistogramSet(s), got {type(capture).__name__}",
            "pass the .h5 file's path, or nl.read_capture(path)")
    return sets, INTERNAL if frame is None else frame, None


def _backgrounds(background, sets) -> list | None:
    """A target-free capture (path, set or sets) as one set per laser point, or None."""
    if background is None:
        return None
    if isinstance(background, (str, Path)):
        from ..io.ytal.capture import read_capture
        background = read_capture(background)
    backgrounds = [background] if isinstance(background, HistogramSet) else list(background)
    require(len(backgrounds) == len(sets), "background", f"has {len(backgrounds)} laser "
            f"point(s), the capture {len(sets)}", "record the background with the same "
            "laser points as the capture")
    return backgrounds


def measured_processing(sets, background, *, negatives, pulses, h_s, calibrated, preprocess):
    """The measured-data steps (localization.measured: time zero, gate, background, response,
    bins, pile-up), or with preprocess=False the background alone: (sets, reports, h)."""
    backgrounds = _backgrounds(background, sets)
    if preprocess:
        from .measured import process_capture
        sets, reports, h, _ = process_capture(sets, backgrounds, negatives=negatives,
                                              pulses=pulses, h_s=h_s, calibrated=calibrated)
        return sets, reports, h
    require(pulses is None, "pulses", "the pile-up correction is a processing step, and "
            "preprocess is off", "pass preprocess=True, or leave pulses out")
    if backgrounds is not None:
        from .background import subtract_background
        sets = [subtract_background(h, b, negatives=negatives) for h, b in zip(sets, backgrounds)]
    return sets, [None] * len(sets), filter_window(sets[0].time_axis.dt_s, h_s)


def _calibrated(sets, calibration):
    """The sets with the calibration applied; the calibration."""
    if calibration is None:
        return sets, None
    from ..io.calibration import (
        fit_calibration,
        read_calibration_pairs,
        with_calibration,
    )
    if isinstance(calibration, (str, Path)):  # a CSV of (path, peak time) pairs: Eq. 26
        calibration = fit_calibration(*read_calibration_pairs(calibration))
    calibration = getattr(calibration, "calibration", calibration)  # a CalibrationFit's
    return [with_calibration(h, calibration) for h in sets], calibration


# The model fit locates paired and confocal layouts on nlos_cl's simulations (0.8 mm, tests/
# test_paired.py) but misses the measured ones it has met (CC-SOCR: plate Birge ratio 370-500,
# depth 1.34 m on 6 points, 7-37 s): by default such captures get the paper's argmax.
def _locate_point(i, hist, frame, region, derived, *, h_s, estimator, log_mode, return_map,
                  backend, names, notes=(), processing=None, seen=None) -> PointLocation:
    """The paper's argmax on the region (refined on a fine zoom where the derived region had to
    be coarsened), then the estimator on the final grid; warnings collected, not raised.
    seen: what the filter reads where it is not `hist` (`_filter_input`); the fit reads hist."""
    from ..ops.signals import upload
    seen = hist if seen is None else seen
    log_mode = auto_log_mode(hist.n_detectors) if log_mode is None else bool(log_mode)
    raw = upload(hist, backend)  # once: filtered here, and fitted by the model estimator
    filtered = gauss_filter(raw if seen is hist else upload(seen, backend), h_s)
    grid = region
    if derived and min(region.step) > region_step(hist, h_s) * 1.001:
        coarse = locate(_spread(seen, filtered, h_s, backend), region, log_mode=log_mode,
                        estimator="paper", detect=False)  # the final grid's call detects
        grid = zoom_region(coarse.position, region, hist, h_s)
    notes = list(notes)
    if hist.paired and not capabilities_of(estimator).paired:
        notes.append(f"the {estimator.name} estimator fits layouts with one laser spot, and this "
                     "capture gives each histogram its own: located with the paper's argmax")
        estimator = ArgmaxSpread()
    with pywarnings.catch_warnings(record=True) as caught:
        pywarnings.simplefilter("always")
        loc = locate(filtered, grid, log_mode=log_mode, estimator=estimator, raw=raw,
                     return_map=return_map)
    notes += [str(w.message) for w in caught]
    if not loc.detected:
        notes.append(loc.detection.message)
    elif on_region_edge(loc.position, region):
        ranges = ", ".join(f"{a} {lo:.3g}..{hi:.3g} m"
                           for a, (lo, hi) in zip(frame.axes, frame.ranges(region)))
        notes.append(f"the answer lies on the search region's edge ({ranges}), so the target "
                     f"may be outside it. Fix: widen it with {names[0]} (ranges along the "
                     "file's axes) or record a longer time window")
    return PointLocation(i, hist.laser_spot, loc, grid, region, log_mode, frame, tuple(notes),
                         processing)


def _filter_input(hist: HistogramSet, processing: dict | None):
    """(`hist`, processing), or where it was recorded through a gate, a copy with each gate's
    outside filled with the level inside its edge (measured.gated.ungated): the filter, the
    detection, the search region and the argmax read that; the fit the data as recorded. The
    processing report gets a `gated` entry then."""
    from .measured.gated import gate_bounds, gated_report, ungated
    data = np.asarray(hist.data)
    if data.ndim != 2 or data.shape[1] < 2:
        return hist, processing
    bounds = gate_bounds(data)
    report = gated_report(bounds, data.shape[1])
    if report is None:
        return hist, processing
    return hist.with_data(ungated(data, bounds)), dict(processing or {}, gated=report)


def _spread(hist, filtered, h_s, backend):
    """The coarse region's search needs only where the answer is, not its last digit: with
    more than SEARCH_DETECTORS histograms it scores that many, spread over the wall (4,096 of
    CC-SOCR: ~64x fewer cell-detector pairs), and the zoom is scored with all of them."""
    if hist.n_detectors <= SEARCH_DETECTORS:
        return filtered
    from ..ops.signals import upload
    rows = farthest_points(np.hstack([hist.detector_spots, hist.laser_spots]), SEARCH_DETECTORS)
    return gauss_filter(upload(hist.select(rows), backend), h_s)


def locate_capture(capture, *, region=None, step_m: float | None = None,
                   h_s: float | None = None, estimator=None, targets=None, log_mode=None,
                   background=None, negatives: str = "keep", calibration=None,
                   return_map: bool = False, backend=None, frame: CaptureFrame | None = None,
                   names=REGION_NAMES, pulses: int | None = None,
                   preprocess: bool = True) -> CaptureLocation:
    """Locate every laser point of a capture, as `nlos-cl locate` does.

    capture: a y-tal file's path, or HistogramSet(s) (ours; `frame` says which frame to report
    in, default ours). region: None (derived from the capture), three (low, high) ranges along
    the file's axes at step_m, or a Grid of ours. estimator: 'model' (with `targets` plates, or
    'auto': every target the data support, up to 3; None: one, and more where the data hold
    separate objects, localization.separate), 'paper', an estimator object, or None: 'model', and the paper's argmax for paired
    and confocal captures (estimators.PAIRED_LOCATE_NOTE says why, in the point's warnings). log_mode: None = auto_log_mode(detectors).
    background: a target-free capture (path or sets) subtracted first, bins below 0 handled by
    `negatives`; calibration: a CSV of (path m, peak time s) pairs (Eq. 26), a PathCalibration
    or a CalibrationFit. return_map: keep each final grid's score map (internal.score_map).
    names: how errors and warnings name the region and step_m options (a CLI: its flags).
    h_s: the Gauss filter's window; None: from the direct return's width where the capture has
    one, else the paper's 0.65 ns or 2 bins, whichever is wider. preprocess: the measured-data steps (measured_processing;
    each point's `processing` says what they found); pulses: laser pulses per histogram for
    the pile-up correction (off without it). Warnings (e.g. an unobservable height) are
    collected in each point's `warnings`, not raised.
    """
    require(h_s is None or isinstance(h_s, (int, float)) and math.isfinite(h_s) and h_s > 0,
            "h_s",
            f"the filter window must be a positive time in seconds, got {h_s!r}",
            "pass e.g. 0.65e-9 (the paper's h)")
    from ..ops.backend import resolve_backend
    given, targets = targets, 1 if targets is None else targets
    est, _ = choose_estimator(estimator, targets=targets)  # checked before any work
    sets, frame, source = _sets(capture, frame)
    sets, reports, h_s = measured_processing(
        sets, background, negatives=negatives, pulses=pulses, h_s=h_s,
        calibrated=calibration is not None, preprocess=bool(preprocess))
    sets, cal = _calibrated(sets, calibration)
    backend = resolve_backend(backend)
    points = []
    for i, hist in enumerate(sets):
        # a gate's outside filled for the filter (measured.gated), and said in `processing`
        seen, processing = _filter_input(hist, reports[i])
        grid, derived = search_region(seen, frame, region, step_m, h_s, names=names)
        point_est, note = (choose_estimator(None, targets=targets, paired=True)
                           if estimator is None and hist.paired else (est, None))
        if isinstance(estimator, str | None) and isinstance(point_est, PaperArgmax):
            point_est = ArgmaxSpread()  # the paper's answer, with its likelihood's spread
        def located(chosen, i=i, hist=hist, grid=grid, derived=derived, note=note, seen=seen,
                    processing=processing):
            return _locate_point(i, hist, frame, grid, derived, h_s=h_s, estimator=chosen,
                                 log_mode=log_mode, return_map=bool(return_map),
                                 backend=backend, names=names, notes=[note] if note else [],
                                 processing=processing, seen=seen)
        if given is None and estimator in (None, "model"):  # one, or separate objects
            point = one_or_more(point_est, located)
        else:
            point = located(point_est)
        points.append(point)
    return CaptureLocation(tuple(points), frame, source, getattr(backend, "name", str(backend)),
                           h_s, cal)
