"""The search region a capture can see, and the zoomed grid around an answer.

`default_region(histograms, h_s)`, in our internal frame (nlos_cl.io.ytal.frames):

- extent: a cell is scored by every detector only if its hidden path |c - O| + |c - D_i| fits
  the time window, i.e. is at most L_i = a t_end + b_i (the calibration at the window's end),
  and no target is farther than its histograms' signal reaches (signal_reach: the last bin
  above the noise floor + 0.5 m; a row without one does not bound).
  That is an ellipsoid with foci O, D_i and major axis L_i; the region is the intersection of
  their axis-aligned bounding boxes, cut to the hidden half-space y >= step.
- height: when the laser spot and all detector spots lie on one line, every ellipsoid is
  symmetric about that line and the height is unobservable: a line along x gives the plane
  z = the spots' mean height (the paper's search plane), a line along z the plane x = mean x.
  Otherwise the region is 3-D.
- step: the filtered pulse has a path width sigma_p = a max(h/3, dt) (h/3 is the filter's
  sigma, dt one bin); a cell step s moves the ellipse path by at most 2 s, so s = sigma_p / 4
  keeps the peak's neighbours inside it for the sub-cell refinement; rounded down to 1, 2 or
  5 x 10^k (the paper's h = 0.65 ns gives its 1 cm). If the region would exceed `max_cells`
  (4 million), the step is coarsened until it fits: search a zoomed grid around the answer
  (`zoom_region`) for the fine position."""
from __future__ import annotations

import math

import numpy as np

from ..core.errors import require
from ..core.grid import Grid
from ..core.stats import row_median
from ..core.histograms import HistogramSet
from ..io.ytal.frames import require_locatable
from ..ops.gauss_filter import filter_window

MAX_CELLS = 4_000_000
ALONG_AXIS_COS = math.cos(math.radians(1))  # a line within 1 deg of an axis is along it
# signal_reach: a bin is signal above the row's median + this many robust sigma (a false bin
# among 60,000 of white noise: ~6e-5), and the region reaches this much hidden path beyond the
# last one (the filtered pulse's tail and a target's far edge beyond its last bright bin).
SIGNAL_SIGMAS = 6.0
REACH_MARGIN_M = 0.5


def line_direction(points) -> np.ndarray | None:
    """The direction of the line through all points, or None when they do not lie on one
    (perpendicular spread above 1 mm or 0.1 % of the line's length)."""
    centred = points - points.mean(axis=0)
    _, s, vt = np.linalg.svd(centred, full_matrices=False)
    length = float(np.ptp(centred @ vt[0]))
    spread = float(np.max(np.abs(centred - np.outer(centred @ vt[0], vt[0])).sum(axis=1)))
    return vt[0] if spread <= max(1e-3, 1e-3 * length) else None


def unseen_axis(points) -> int | None:
    """The axis collinear wall points (lasers and detectors) cannot see: 2 (z) for a line
    along x, 0 (x) for a line along z (rotating a hidden point about their line changes no
    path; the axis is held on the points' mean plane). None where they do not lie on one line
    or their line is along neither axis (then no one axis is unseen)."""
    line = line_direction(np.asarray(points, dtype=np.float64))
    if line is not None and abs(line[0]) > ALONG_AXIS_COS:
        return 2
    if line is not None and abs(line[2]) > ALONG_AXIS_COS:
        return 0
    return None


def _nice_step(step: float) -> float:
    """Round down to 1, 2 or 5 x 10^k."""
    k = math.floor(math.log10(step))
    return max(m * 10.0 ** k for m in (1, 2, 5) if m * 10.0 ** k <= step * (1 + 1e-9))


def region_step(histograms: HistogramSet, h_s: float | None = None) -> float:
    """The fine cell size: a quarter of the filtered pulse's path width a max(h/3, dt) (h_s
    None: the filter's default window for these bins)."""
    h_s = filter_window(histograms.time_axis.dt_s, h_s)
    require(isinstance(h_s, (int, float)) and math.isfinite(h_s) and h_s > 0, "h_s",
            f"the filter window must be a positive time in seconds, got {h_s!r}",
            "pass e.g. 0.65e-9 (the paper's h)")
    a = histograms.calibration.a_m_per_s
    return _nice_step(a * max(h_s / 3.0, histograms.time_axis.dt_s) / 4.0)


def signal_reach(sets) -> np.ndarray | None:
    """(D,) the hidden path each row's signal reaches, over `sets` (HistogramSets of one
    layout): the end of its last bin above the row's floor + SIGNAL_SIGMAS robust sigma (any
    bin above the floor where most bins equal it: processed or noise-free data), plus
    REACH_MARGIN_M; +inf for a row with no such bin. None when no row has one."""
    reach = None
    for h in sets:
        data = np.asarray(h.data, dtype=np.float64)
        floor = row_median(data)[:, None]
        sigma = 1.4826 * row_median(np.abs(data - floor), overwrite=True)[:, None]
        above = data > floor + SIGNAL_SIGMAS * sigma
        last = np.where(above.any(axis=1), data.shape[1] - np.argmax(above[:, ::-1], axis=1), -1)
        axis = h.path_axis()
        path = np.where(last >= 0, axis.start_m + last * axis.step_m + REACH_MARGIN_M, np.inf)
        reach = path if reach is None else np.maximum(reach, path)
    return None if reach is None or not np.isfinite(reach).any() else reach


def visible_box(histograms: HistogramSet, reach=None) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) corners of the box around every point all detectors' windows reach (and,
    with `reach` (D,), only as far as each row's signal does: signal_reach)."""
    h = histograms
    reach = h.path_axis().stop_m if reach is None else np.minimum(h.path_axis().stop_m, reach)
    lasers = h.laser_spots  # each histogram's (paired and confocal captures: its own)
    baseline = np.linalg.norm(h.detector_spots - lasers, axis=1)
    i = int(np.argmin(reach - baseline))
    require(reach[i] > baseline[i], "time_axis",
            f"the window ends at a hidden path of {reach[i]:.3g} m for detector {i}, shorter "
            f"than the {baseline[i]:.3g} m between its spot and the laser spot: no hidden point "
            "is in view", "record a longer time window, or check the calibration (t_start)")
    centre = 0.5 * (h.detector_spots + lasers)
    semi_major = 0.5 * reach
    semi_minor2 = semi_major ** 2 - (0.5 * baseline) ** 2
    u = (h.detector_spots - lasers) / np.maximum(baseline, 1e-12)[:, None]  # confocal: 0
    half = np.sqrt(semi_major[:, None] ** 2 * u ** 2 + semi_minor2[:, None] * (1 - u ** 2))
    return (centre - half).max(axis=0), (centre + half).min(axis=0)


def default_region(histograms: HistogramSet, h_s: float | None = None, *,
                   max_cells: int = MAX_CELLS, reach_from=None) -> Grid:
    """The search grid (internal frame) a capture can see; the rules are in the module doc.
    reach_from: HistogramSets of this layout whose signal bounds the region (signal_reach;
    default: `histograms` itself; () for the whole window)."""
    h = histograms
    require_locatable(h)
    step = region_step(h, h_s)
    lo, hi = visible_box(h, signal_reach([h] if reach_from is None else reach_from))
    lo[1] = max(lo[1], 0.0)
    spots = np.vstack([h.laser_spots, h.detector_spots])
    flat = unseen_axis(spots)  # the internal axis collapsed to one plane, if unobservable
    if flat is not None:
        lo[flat] = hi[flat] = float(spots[:, flat].mean())
    require(hi[1] > 0 and bool(np.all(hi >= lo)), "time_axis", "the detectors' windows share "
            "no hidden point in front of the wall", "record a longer time window")
    dims = 3 - (flat is not None)
    box_lo = lo.copy()
    while True:
        # cells on whole multiples of the step (as a user's round grid would be): answers
        # that do not depend on where the window happened to end
        lo = np.where(hi > box_lo, np.ceil(box_lo / step - 1e-9) * step, box_lo)
        lo[1] = step
        shape = [int(math.floor(max(e, 0.0) / step + 1e-9)) + 1 for e in (hi - lo)]
        if int(np.prod(shape)) <= max_cells:
            break
        step = max(step * 1.05, step * (np.prod(shape) / max_cells) ** (1 / dims))
    require(hi[1] >= lo[1], "time_axis", f"the window only reaches {hi[1]:.3g} m in front of "
            "the wall, less than one grid step", "record a longer time window")
    return Grid(tuple(lo), (step,) * 3, tuple(shape))


def zoom_region(position, grid: Grid, histograms: HistogramSet, h_s: float | None = None, *,
                cells: int = 4) -> Grid:
    """A fine grid (the region_step) around `position`, `cells` coarse steps each way: search
    it after a coarse default_region whose step was coarsened to fit max_cells."""
    fine = min(region_step(histograms, h_s), min(grid.step))
    p = np.asarray(position, dtype=np.float64).reshape(3)
    lo, hi = [], []
    for axis, s, n, v in zip(grid.axes(), grid.step, grid.shape, p):
        if n == 1:
            lo.append(float(axis[0]))
            hi.append(float(axis[0]))
        else:
            lo.append(max(float(axis[0]), v - cells * s))
            hi.append(min(float(axis[-1]), v + cells * s))
    lo[1] = max(lo[1], fine)
    shape = tuple(int(math.floor((b - a) / fine + 1e-9)) + 1 for a, b in zip(lo, hi))
    return Grid(tuple(lo), (fine,) * 3, shape)


def on_region_edge(position, grid: Grid) -> bool:
    """True when `position` lies in the outermost cell layer of `grid` (or outside it) along an
    axis with more than one cell: the answer may be beyond the region, widen it."""
    p = np.asarray(position, dtype=np.float64).reshape(3)
    for axis, s, n, v in zip(grid.axes(), grid.step, grid.shape, p):
        if n > 1 and (v - axis[0] < s or axis[-1] - v < s):
            return True
    return False
