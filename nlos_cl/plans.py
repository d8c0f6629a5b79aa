"""Plans: objects built once for a setup, then called once per frame (pyvkfft's way with FFT
plans). `GaussFilter` fixes the filter's taps for a time axis; `Locator` fixes the grid, the
wall geometry, the score axis, the estimator and the score buffer, so a stream of frames pays
only for the frame: its upload (if it comes from the host), the kernels, and the argmax read.
"""
from __future__ import annotations

import math

import numpy as np

from .constants import LOG_FLOOR, PAPER_H_S
from .errors import require
from .estimators import Location, Scored, as_estimator
from .grid import Grid
from .histograms import Layout
from .ops.gauss_filter import gauss_taps
from .paths import TimeAxis
from .signals import Signals, as_signals


def _layout_of(value) -> Layout:
    return value if isinstance(value, Layout) else value.layout


class GaussFilter:
    """The paper's Gauss filter (Eq. 24) for one time axis: a Gaussian of sigma = h / 3 over
    the window [t - h, t + h]. `plan(signals) -> Signals` on the signals' backend."""

    def __init__(self, h_s: float = PAPER_H_S, time_axis: TimeAxis | None = None, *,
                 backend=None):
        require(isinstance(h_s, (int, float)) and not isinstance(h_s, bool)
                and math.isfinite(h_s) and h_s > 0, "h_s",
                f"the filter window must be a positive time in seconds, got {h_s!r}",
                "pass e.g. 0.65e-9 (the paper's h)")
        self.h_s = float(h_s)
        self.backend = backend
        self._axis, self._taps = None, None
        if time_axis is not None:
            self._prepare(time_axis)

    def _prepare(self, axis: TimeAxis):
        require(self.h_s >= axis.dt_s, "h_s", f"window {self.h_s:.3e} s is narrower than one "
                f"bin ({axis.dt_s:.3e} s), so the filter would only rescale the data",
                "use h_s of at least one bin width, typically 0.65e-9")
        require(self.h_s < axis.n_bins * axis.dt_s, "h_s",
                f"window {self.h_s:.3e} s is longer than the whole record "
                f"({axis.n_bins * axis.dt_s:.3e} s)", "use a smaller h_s or a longer time axis")
        self._axis, self._taps = axis, gauss_taps(self.h_s, axis.dt_s)

    @property
    def taps(self) -> np.ndarray | None:
        return self._taps

    def __call__(self, signals) -> Signals:
        sig = as_signals(signals, self.backend)
        if sig.layout.time_axis != self._axis:
            self._prepare(sig.layout.time_axis)
        return sig.derive(sig.backend.call("gauss_filter", sig.handle, self._taps))


class Locator:
    """Score a grid for one wall layout and estimate the target's position, frame after frame.

    `Locator(layout, grid)` where layout is a `Layout`, or histograms/signals to take it from;
    `locator(filtered_signals) -> Location`. log_mode scores by the sum of log-likelihoods
    (for many detectors); the estimator is a name ('paper') or an object (nlos_cl.estimators).
    """

    def __init__(self, layout, grid: Grid | None = None, *, estimator=None,
                 log_mode: bool = False, backend=None):
        layout = _layout_of(layout)
        grid = Grid() if grid is None else grid
        require(isinstance(grid, Grid), "grid", f"expected a nlos_cl.Grid, got "
                f"{type(grid).__name__}", "build one with Grid.from_ranges(x=(0, 6), y=(0.01, 6), "
                "step_m=0.01)")
        self.layout, self.grid, self.log_mode = layout, grid, bool(log_mode)
        self.estimator = as_estimator(estimator)
        self.backend = backend
        axis = layout.path_axis()
        self._path0, self._inv_dpath = axis.centre0_m, 1.0 / axis.step_m
        self._scores = None  # the score buffer, reused frame after frame

    def scores(self, signals: Signals):
        """The grid's joint likelihood on the signals' backend (the plan's own buffer)."""
        be, lay = signals.backend, self.layout
        stats = be.call("row_stats", signals.handle)
        self._scores = be.call("ellipse_score", signals.handle, stats, lay.detector_spots,
                               lay.laser_spot, self._path0, self._inv_dpath, self.grid,
                               self.log_mode, LOG_FLOOR, out=self._scores)
        return self._scores

    def __call__(self, signals, *, raw=None, return_map: bool = False) -> Location:
        """Locate from filtered signals; `raw`: the same frame unfiltered, for estimators that
        fit a model to the histograms (the paper's argmax does not need it)."""
        sig = as_signals(signals, self.backend)
        require(sig.layout.shape == self.layout.shape, "signals", f"shape {sig.layout.shape} "
                f"differs from the plan's {self.layout.shape}", "build a Locator for this layout")
        if sig.layout is not self.layout:  # the same setup frame after frame: one comparison
            require(np.array_equal(sig.layout.detector_spots, self.layout.detector_spots)
                    and sig.layout.time_axis == self.layout.time_axis, "signals",
                    "come from another wall layout or time axis than the plan's",
                    "build a Locator for this layout")
        scores = self.scores(sig)
        raw = None if raw is None else as_signals(raw, sig.backend)
        scored = Scored(sig.backend, scores, self.grid, self.log_mode, sig.n_detectors, sig, raw)
        estimate = self.estimator.estimate(scored)
        full = sig.backend.to_numpy(scores) if return_map else None
        return Location.of(estimate, self.grid, sig.layout.truth, full, self.estimator.name)

