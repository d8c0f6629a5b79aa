"""The Locator plan: built once for a setup, called once per frame (pyvkfft's way with FFT
plans). `Locator` fixes the grid, the wall geometry, the score axis, the estimator and the
score buffer, so a stream of frames pays only for the frame: its upload (if it comes from the
host), the kernels, and the argmax read."""
from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from ..core.constants import LOG_FLOOR, PAPER_H_S, SPEED_OF_LIGHT
from ..core.errors import require
from ..core.grid import Grid
from ..core.tuning import AUTO_TRIALS
from ..core.histograms import HistogramSet
from ..core.stats import median
from ..ops.argmax_patch import decode
from ..ops.backend import NumpyBackend
from ..ops.signals import Signals, as_signals
from .estimate import Location, Scored, capabilities_of
from .detection import detect, raw_floor_of, reachable_bins
from .estimators import as_estimator
from .filter import layout_of
from .paper import PaperArgmax
from .search import SEARCHES, CoarseToFine
from .window import WindowSearch, checked_box

# The width of a filtered signal in hidden-path metres, where the caller gives none: the
# paper's filter, sigma = h / 3 (the 30 ps pulse adds 1 % in quadrature). It sets only the
# coarse-to-fine search's speed, never its answer.
PAPER_SIGNAL_WIDTH_M = SPEED_OF_LIGHT * PAPER_H_S / 3.0
SEARCHES_TRIED = ("coarse_to_fine", "exhaustive")
# "auto" also tries coarse to fine with blocks 2 cells wider than the signal width allows:
# where the bound prunes well, fewer coarse cells outweigh more candidate cells (the consumer
# sensor's walk, 3.5 M cells: blocks of 5 8.1 ms, of 3 14.5 ms; the paper's plane: 5-9 alike)
WIDE_BLOCKS = "coarse_to_fine_wide"


class SearchChoice:
    """search="auto": time each search on the first frames (AUTO_TRIALS each, after one
    warm-up each: it builds the programs) and keep the one with the lower median. The answer
    is the same either way; only the speed differs between grids and devices. modes: the
    searches tried (coarse to fine at the signal width's blocks, at WIDE_BLOCKS, exhaustive)."""

    def __init__(self, search: str, modes=SEARCHES_TRIED):
        self.chosen = None if search == "auto" else search
        self.modes = tuple(modes)
        self._trials = []  # (search, seconds) of the first frames

    def mode(self) -> str:
        return self.chosen or self.modes[len(self._trials) % len(self.modes)]

    def learn(self, mode: str, seconds: float) -> None:
        if self.chosen is not None:
            return
        self._trials.append((mode, seconds))
        n = len(self.modes)
        if len(self._trials) < n * (AUTO_TRIALS + 1):
            return
        med = {m: median([t for k, t in self._trials[n:] if k == m])
               for m in self.modes}
        self.chosen = min(self.modes, key=lambda m: med[m])


class Locator:
    """Score a grid for one wall layout and estimate the target's position, frame after frame.

    `Locator(layout, grid)` where layout is a `Layout`, or histograms/signals to take it from;
    `locator(filtered_signals) -> Location`. log_mode scores by the sum of log-likelihoods
    (for many detectors); the estimator is a name ('paper') or an object (localization.estimate).

    search: "coarse_to_fine" scores only the blocks of cells whose upper bound can hold the
    best cell (localization/search.py): the same argmax cell, score and 3 x 3 x 3 neighbourhood
    as "exhaustive" (every cell). "auto" (default) times them (and blocks 2 cells wider) on
    the first frames and keeps the fastest, for `local` (the paper's) and `from_paper`
    estimators (the model fit); others, and return_map=True, score every cell. With the
    paper's estimator a frame is one small read: the search stays on the device.
    signal_width_m: the filtered signal's width in hidden-path metres (default: the paper's
    filter, c h / 3 = 6.5 cm); it sets the coarse grid's step, i.e. only the speed.
    within (per call): a box (lo, hi) to search the argmax in (localization/window.py).
    """

    def __init__(self, layout, grid: Grid | None = None, *, estimator=None,
                 log_mode: bool = False, backend=None, search: str = "auto",
                 signal_width_m: float | None = None):
        layout = layout_of(layout)
        grid, width = _checked_options(grid, search, signal_width_m)
        self.layout, self.grid, self.log_mode = layout, grid, bool(log_mode)
        self.estimator = as_estimator(estimator)
        self.backend = backend
        axis = layout.path_axis()
        self._path0, self._inv_dpath = axis.centre0_m, 1.0 / axis.step_m
        self._scores = None  # the score buffer, reused frame after frame
        self._stats = self._result = None  # row stats and the fused searches' result, reused
        self._geometry = (layout.detector_spots, layout.laser_spot, self._path0,
                          self._inv_dpath, self.log_mode, LOG_FLOOR)
        self.capabilities = capabilities_of(self.estimator)
        require(self.capabilities.paired or not layout.paired, "estimator",
                f"{self.estimator.name!r} fits layouts with one laser spot for every histogram, "
                "and this one gives each histogram its own (a paired or confocal capture)",
                "pass estimator='paper' (its argmax locates paired and confocal captures)")
        can = self.capabilities  # a search for those that need the neighbourhood or argmax
        self.search = search if can.local or can.from_paper else "exhaustive"
        self._plans, self._choice = _search_plans(grid, self._inv_dpath, width, self.search)
        self._search = self._plans["coarse_to_fine"]  # the plan of the frame at hand
        self.windows = WindowSearch(grid)  # `within`: windows.last, the last frame's, or None
        # what the last frame's search did (search.Found), and its argmax's (ix, iy, iz)
        self.last_search = self.last_cell = None
        self._window = None  # each row's bins a target in the grid can reach (detection)
        self._kept = {}  # the host array a large record's rows are read into (detected_in)

    @property
    def chosen(self) -> str | None:
        """The search kept for this grid (None while "auto" is still timing them)."""
        return "coarse_to_fine" if self._choice.chosen == WIDE_BLOCKS else self._choice.chosen

    def _args(self, signals: Signals):
        stats = signals.backend.call("row_stats", signals.handle, out=self._stats)
        self._stats = stats
        return (stats,) + self._geometry

    def scores(self, signals: Signals, args=None):
        """The grid's joint likelihood on the signals' backend (the plan's own buffer)."""
        _check_map(self.grid)
        args = self._args(signals) if args is None else args
        self._scores = signals.backend.call("ellipse_score", signals.handle, *args[:5],
                                            self.grid, *args[5:], out=self._scores)
        return self._scores

    def _scored(self, sig: Signals, raw, return_map: bool, mode: str, rows=None) -> Scored:
        """Scores where the estimator looks: the whole grid, or (coarse to fine) the best
        cell's neighbourhood on a sub-grid of the same cells. rows: Scored.host_rows."""
        args, found = self._args(sig), None
        if mode == "coarse_to_fine" and not return_map and self._search.useful:
            found = self._search.run(sig.backend, sig.handle, args)
        self.last_search = found
        if found is None:
            sub, scores = self.grid, self.scores(sig, args)
        else:
            sub, scores = self._search.neighbourhood(sig.backend, sig.handle, args, found.index)
        return Scored(sig.backend, scores, sub, self.log_mode, sig.n_detectors, sig, raw,
                      host_rows=rows)

    def __call__(self, signals, *, raw=None, prior=None, return_map: bool = False,
                 detect: bool = True, within=None) -> Location:
        """Locate from filtered signals; `raw`: the same frame unfiltered, for estimators that
        fit a model to the histograms (the paper's argmax does not need it); `prior`: where
        the targets are expected (a localization.estimate.Prior, e.g. a tracker's prediction),
        for estimators that start a fit from it. detect: first test the frame for any target
        signal (localization.detection; ~1 ms for 3 x 60,000 bins); where there is none the
        estimator is not run, and the Location has no targets (`detected` False) and the paper's
        argmax as its position. within: a box (lo, hi) to search the argmax in (class doc)."""
        box, self.windows.last = None if within is None else checked_box(within), None
        sig = _checked(as_signals(signals, self.backend), self.layout)
        trial = self._choice.mode()  # one of _search_plans' (WIDE_BLOCKS: coarse to fine)
        self._search, mode = self._plans.get(trial, self._search), _kind(trial)
        if detect and self._window is None:  # the detection's bins, once
            self._window = reachable_bins(self.layout, self.grid)
        rows, detection = detected_in(sig, self._window, self._kept, raw) if detect else \
            (None, None)
        if detection is not None and not detection.detected and not return_map:
            return Location.undetected(self._paper(sig, mode, rows), self.grid,
                                       sig.layout.truth, detection, self.estimator.name)
        start = time.perf_counter()
        fusable = not return_map and (mode == "exhaustive"
                                      or self._search.fusable(sig.n_detectors))
        can, raw = self.capabilities, _raw_for(self.estimator, raw, sig.backend)
        timed = not return_map  # search="auto" learns from this frame's search time
        if fusable and can.is_paper:
            estimate, full = self._fused(sig, mode, box), None
        elif fusable and can.from_paper:  # a model fit starts from the fused search's one read
            paper, timed = self._fused(sig, mode, box), False  # the search timed alone (the
            self._choice.learn(trial, time.perf_counter() - start)  # fit's noise had chosen it)
            scored = Scored(sig.backend, None, self.grid, self.log_mode, sig.n_detectors, sig,
                            raw, paper=paper, host_rows=rows)
            estimate, full = _estimate(self.estimator, scored, prior), None
        else:
            scored = self._scored(sig, raw, return_map, mode, rows)
            estimate = _in_grid(_estimate(self.estimator, scored, prior), self.grid, self.last_search)
            full = sig.backend.to_numpy(scored.scores) if return_map else None
        if timed:
            self._choice.learn(trial, time.perf_counter() - start)
        if detection is not None and not detection.detected:  # a map was asked for
            return Location.undetected(estimate, self.grid, sig.layout.truth, detection,
                                       self.estimator.name, full)
        return Location.of(estimate, self.grid, sig.layout.truth, full, self.estimator.name,
                           detection)

    def _paper(self, sig: Signals, mode: str, rows=None):
        """The paper's estimate for any number of detectors: fused (one read) where the search
        takes them (fused_search scores up to DET_TILE in one pass), else from the scored
        neighbourhood, as a frame with a target of that many detectors is located."""
        if mode == "exhaustive" or self._search.fusable(sig.n_detectors):
            return self._fused(sig, mode)
        scored = self._scored(sig, None, False, mode, rows)
        return _in_grid(PaperArgmax().estimate(scored), self.grid, self.last_search)

    # ------------------------------------------------------------ the paper's argmax, fused
    def _fused(self, sig: Signals, mode: str, box=None):
        """The paper's estimate with one read, on the device: in the window `box` where that
        is cheaper (window.py; once "auto" has chosen the grid's search), else the fused search
        (coarse to fine) or the whole map's argmax and its neighbourhood (exhaustive)."""
        be, found = sig.backend, None
        # (windows only after "auto" has chosen, so its trials time whole-grid searches alone)
        hit = None if box is None or self._choice.chosen is None else self.windows.run(
            be, sig.handle, lambda: self._args(sig), box, self._result)
        if hit is not None:
            index, best, patch, self._result = hit
            self.last_search, self.last_cell = None, index
            return PaperArgmax().from_patch(index, best, patch, self.grid, self.log_mode,
                                            sig.n_detectors)
        if mode == "coarse_to_fine":
            found, patch, self._result = self._search.fused(be, sig.handle, self._geometry,
                                                            self._result)
        if found is None:  # exhaustive (or no candidate block: score every cell)
            scores = self.scores(sig, self._args(sig))
            self._result = be.call("argmax_patch", scores, out=self._result)
            index, best, _, patch = decode(be.to_numpy(self._result))
        else:
            index, best = found.index, found.score
        self.last_search, self.last_cell = found, index
        self.windows.searched(found, self._search)
        return PaperArgmax().from_patch(index, best, patch, self.grid, self.log_mode,
                                        sig.n_detectors)


def _search_plans(grid: Grid, inv_dpath, width: float, search: str) -> tuple:
    """({"coarse_to_fine": blocks for the signal width, WIDE_BLOCKS: 2 cells wider}, the
    SearchChoice among them and exhaustive; exhaustive alone where blocks are no use)."""
    base = CoarseToFine(grid, inv_dpath, float(width))
    plans = {"coarse_to_fine": base,
             WIDE_BLOCKS: CoarseToFine(grid, inv_dpath, float(width), base.factor + 2)}
    # the signal width's blocks first: a one-shot locate (one frame) searches as before
    return plans, SearchChoice(search if base.useful else "exhaustive",
                               ("coarse_to_fine", WIDE_BLOCKS, "exhaustive"))


def _kind(trial: str) -> str:
    return "exhaustive" if trial == "exhaustive" else "coarse_to_fine"


def _checked_options(grid, search, signal_width_m) -> tuple:
    """(the grid, the signal width in path metres), each checked."""
    grid = Grid() if grid is None else grid
    require(isinstance(grid, Grid), "grid", f"expected a nlos_cl.Grid, got "
            f"{type(grid).__name__}", "build one with Grid.from_ranges(x=(0, 6), y=(0.01, 6), "
            "step_m=0.01)")
    require(search in SEARCHES, "search", f"unknown search {search!r}",
            f"pass one of {list(SEARCHES)}")
    width = PAPER_SIGNAL_WIDTH_M if signal_width_m is None else signal_width_m
    require(isinstance(width, (int, float)) and math.isfinite(width) and width > 0,
            "signal_width_m", f"must be a positive path length in metres, got {width!r}",
            "pass e.g. 0.065 (c h / 3 for the paper's h)")
    return grid, width


def _check_map(grid: Grid) -> None:
    """A grid scored as one map: within the kernels' index range and the memory limit."""
    from ..core.limits import require_memory
    require(grid.n_cells < 2 ** 31, "grid", f"has {grid.n_cells:.3g} cells to score "
            "as one map, more than the kernels index (2^31)", "search a smaller region or "
            "a coarser step (search='coarse_to_fine' scores a fine grid in parts)")
    require_memory("grid", 4.0 * grid.n_cells, f"scoring {grid.n_cells:.3g} "
                   "cells as one map", "search a smaller region or a coarser step")


def _estimate(estimator, scored: Scored, prior):
    # estimators written before priors take estimate(scored) only
    if prior is None:
        return estimator.estimate(scored)
    return estimator.estimate(scored, prior)


def _checked(sig: Signals, layout) -> Signals:
    require(sig.layout.shape == layout.shape, "signals", f"shape {sig.layout.shape} "
            f"differs from the plan's {layout.shape}", "build a Locator for this layout")
    if sig.layout is not layout:  # the same setup frame after frame: one comparison
        require(np.array_equal(sig.layout.detector_spots, layout.detector_spots)
                and sig.layout.time_axis == layout.time_axis, "signals",
                "come from another wall layout or time axis than the plan's",
                "build a Locator for this layout")
    return sig


# Records at least this large (bytes) are read into a host array the Locator keeps between
# frames (`detected_in`'s `kept`): a fresh one of a 1,024 x 60,042-bin SPAD record (246 MB,
# above glibc's largest mmap threshold, so every new array is new pages) took 0.12-0.64 s to
# read, most of it page faults; below it an array costs nothing to make.
KEEP_ROWS_BYTES = 32 * 2 ** 20


def detected_in(signals: Signals, window, kept=None, raw=None):
    """(the filtered rows on the host as stored, whether they hold target signal in each row's
    reachable bins `window`: localization.detection.detect): one read, which the model fit's
    observation reads too (Scored.host_rows). A large record (KEEP_ROWS_BYTES) on a CPU device
    is mapped in place (Runtime.view), elsewhere read into a host array kept in `kept` for
    the next frame: either way the rows are valid until the Locator's next call. raw: the same frame unfiltered (Signals or HistogramSet), whose white
    bin noise sets the floor of rows without enough unreachable bins (detection.raw_floor)."""
    rows = None
    handle = signals.handle
    large = signals.host is None and handle.nbytes >= KEEP_ROWS_BYTES
    if large and hasattr(signals.backend, "view"):  # a CPU device's buffer, mapped in place
        rows = signals.backend.view(handle)
    if rows is None and kept is not None and large and \
            getattr(signals.backend, "reads_into", False):
        out = kept.get("rows")
        if out is None or out.shape != handle.shape or out.dtype != handle.dtype:
            kept.clear()  # the old one first: never two of them
            out = kept["rows"] = np.empty(handle.shape, handle.dtype)
        rows = signals.backend.read(handle, out=out)
    if rows is None:
        rows = signals.values()
    return rows, detect(rows, window, raw=raw_floor_of(raw, signals))


def _in_grid(estimate, grid: Grid, found):
    """An estimate made on a sub-grid (the coarse-to-fine search's `found`), with the best
    cell's centre as the whole grid computes it (the sub-grid's origin differs from it by
    float64 rounding)."""
    if found is None:
        return estimate
    cell = np.array([o + s * i for o, s, i in zip(grid.origin, grid.step, found.index)])
    shift = cell - estimate.cell_position
    targets = [replace(t, position=t.position + shift) for t in estimate.targets]
    return replace(estimate, cell_position=cell, targets=targets)


def _raw_for(estimator, raw, backend):
    """The unfiltered frame, for estimators that fit it (no upload for the others); one that
    declares no capabilities gets it, as before capabilities were declared."""
    wants = capabilities_of(estimator).needs_raw or not hasattr(estimator, "capabilities")
    if raw is None or not wants:
        return None
    if isinstance(raw, HistogramSet):  # read on the host (the model fit): not uploaded and read
        # back (a SPAD record of 1,024 x 60,000 bins: ~1 s), nor copied
        return Signals(NumpyBackend(), raw.data, 1.0, raw.layout)
    return as_signals(raw, backend)
