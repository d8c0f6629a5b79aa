"""The Gauss filter plan (paper Eq. 24): built once for a time axis, called once per frame
(pyvkfft's way with FFT plans). `GaussFilter` fixes the filter's taps."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..core.errors import require
from ..core.histograms import Layout
from ..core.paths import TimeAxis
from ..core.stats import median, row_median
from ..ops.gauss_filter import filter_window, gauss_taps
from ..ops.signals import Signals, as_signals


def layout_of(value) -> Layout:
    return value if isinstance(value, Layout) else value.layout


class GaussFilter:
    """The paper's Gauss filter (Eq. 24) for one time axis: a Gaussian of sigma = h / 3 over
    the window [t - h, t + h]. `plan(signals) -> Signals` on the signals' backend. h_s: None
    (default) follows the bins: the paper's 0.65 ns, or 2 bins where they are coarser
    (ops.gauss_filter.filter_window); `window_s` is the one in use."""

    def __init__(self, h_s: float | None = None, time_axis: TimeAxis | None = None, *,
                 backend=None):
        require(h_s is None or isinstance(h_s, (int, float)) and not isinstance(h_s, bool)
                and math.isfinite(h_s) and h_s > 0, "h_s",
                f"the filter window must be a positive time in seconds, got {h_s!r}",
                "pass e.g. 0.65e-9 (the paper's h), or leave it out to follow the bins")
        self.h_s = None if h_s is None else float(h_s)
        self.backend = backend
        self._axis, self._taps, self.window_s = None, None, None
        if time_axis is not None:
            self._prepare(time_axis)

    def _prepare(self, axis: TimeAxis):
        h = filter_window(axis.dt_s, self.h_s)
        require(h >= axis.dt_s, "h_s", f"window {h:.3e} s is narrower than one "
                f"bin ({axis.dt_s:.3e} s), so the filter would only rescale the data",
                "use h_s of at least one bin width, or leave it out to follow the bins")
        require(h < axis.n_bins * axis.dt_s, "h_s",
                f"window {h:.3e} s is longer than the whole record "
                f"({axis.n_bins * axis.dt_s:.3e} s)", "use a smaller h_s or a longer time axis")
        self._axis, self._taps, self.window_s = axis, gauss_taps(h, axis.dt_s), h

    @property
    def taps(self) -> np.ndarray | None:
        return self._taps

    def __call__(self, signals) -> Signals:
        sig = as_signals(signals, self.backend)
        if sig.layout.time_axis != self._axis:
            self._prepare(sig.layout.time_axis)
        out = sig.derive(sig.backend.call("gauss_filter", sig.handle, self._taps))
        return replace(out, filtered_h_s=self.window_s)


# Rows that still hold the bin-to-bin noise the paper's filter removes (`looks_unfiltered`):
# the step energy ||x[k+1] - x[k]|| / ||x - median|| per row, against 1 / (sigma sqrt 2), what
# a row smoothed by a Gaussian of sigma bins has at most (white noise through it: exactly that;
# a smooth return: less). Measured, paper's scene at 10 dB: filtered rows 0.6-0.7 of it (h =
# 0.3 or 0.65 ns, 1 or 10 ps bins), unfiltered noisy rows 13x (10 ps) and 130x (1 ps).
# Noise-free unfiltered rows (0.8x: the target's own path spread is wider than the filter)
# and coarse bins (250 ps: the filter's sigma under a bin does little) are not told apart.
UNFILTERED_STEP_FACTOR = 3.0
UNFILTERED_MIN_SIGMA_BINS = 4.0
UNFILTERED_SAMPLE_ROWS = 16  # rows read from the middle of the record: bounded work


def looks_unfiltered(signals: Signals, h_s: float | None = None) -> bool:
    """Do these signals still hold white, bin-to-bin noise that the Gauss filter of window
    h_s would have removed? (The median row of UNFILTERED_SAMPLE_ROWS; False for the Gauss
    filter's own output, where the filter's sigma spans under UNFILTERED_MIN_SIGMA_BINS bins,
    or where the rows are constant.)"""
    dt = signals.layout.time_axis.dt_s
    sigma_bins = filter_window(dt, h_s) / 3.0 / dt
    if signals.filtered_h_s is not None or sigma_bins < UNFILTERED_MIN_SIGMA_BINS:
        return False
    n = signals.n_detectors
    take = min(n, UNFILTERED_SAMPLE_ROWS)
    first = (n - take) // 2
    if signals.host is not None:
        rows = signals.host[first:first + take]
    else:
        from ..ops.backend import read_values
        rows = read_values(signals.backend, signals.handle[first:first + take])
    x = np.asarray(rows, np.float64)
    x = x - row_median(x)[:, None]  # core.stats: np.median would import numpy.ma on the way
    size = np.sqrt(np.einsum("ij,ij->i", x, x))
    step = np.diff(x, axis=1)
    steps = np.sqrt(np.einsum("ij,ij->i", step, step))
    lit = size > 0
    if not lit.any():
        return False
    ratio = median(steps[lit] / size[lit])
    return ratio > UNFILTERED_STEP_FACTOR / (sigma_bins * math.sqrt(2.0))
