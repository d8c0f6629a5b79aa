"""The Gauss filter plan (paper Eq. 24): built once for a time axis, called once per frame
(pyvkfft's way with FFT plans). `GaussFilter` fixes the filter's taps."""
from __future__ import annotations

import math

import numpy as np

from ..core.constants import PAPER_H_S
from ..core.errors import require
from ..core.histograms import Layout
from ..core.paths import TimeAxis
from ..ops.gauss_filter import gauss_taps
from ..ops.signals import Signals, as_signals


def layout_of(value) -> Layout:
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
