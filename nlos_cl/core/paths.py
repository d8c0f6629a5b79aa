"""Time and hidden path: the time axis of a histogram, the calibration that maps arrival time
to hidden path length r1 + r2 (paper Eq. 26), and `PathAxis`, the one place that turns the two
into the hidden path of every bin, per detector. Simulate, locate, capture and the benchmark
all go through `PathAxis`."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .constants import SPEED_OF_LIGHT
from .errors import require


@dataclass(frozen=True)
class TimeAxis:
    """Bins [t0 + k dt, t0 + (k + 1) dt) for k < n_bins; times in seconds from pulse emission."""

    t0_s: float
    dt_s: float
    n_bins: int

    def __post_init__(self):
        require(isinstance(self.t0_s, (int, float)) and math.isfinite(self.t0_s), "time_axis.t0_s",
                f"must be a finite time in seconds, got {self.t0_s!r}", "pass e.g. 2 * 20 / c")
        require(isinstance(self.dt_s, (int, float)) and math.isfinite(self.dt_s)
                and self.dt_s > 0, "time_axis.dt_s",
                f"must be a positive bin width in seconds, got {self.dt_s!r}", "pass e.g. 1e-12")
        require(isinstance(self.n_bins, (int, np.integer)) and self.n_bins >= 2,
                "time_axis.n_bins", f"must be an integer >= 2, got {self.n_bins!r}",
                "pass the number of bins, e.g. 60000")
        object.__setattr__(self, "n_bins", int(self.n_bins))

    @property
    def t_end_s(self) -> float:
        return self.t0_s + self.n_bins * self.dt_s

    def centres(self) -> np.ndarray:
        return self.t0_s + (np.arange(self.n_bins) + 0.5) * self.dt_s

    def edges(self) -> np.ndarray:
        return self.t0_s + np.arange(self.n_bins + 1) * self.dt_s


@dataclass(frozen=True)
class PathCalibration:
    """Hidden path length r1 + r2 (m) = a * t + b[detector], t in seconds (paper Eq. 26).

    For simulated data a = c and b = -(2 d + c mu): the device-to-wall legs and the pulse-peak
    delay mu = 3 sigma are removed. Measured data carry their own fitted line.
    """

    a_m_per_s: float
    b_m: np.ndarray

    def __post_init__(self):
        require(math.isfinite(self.a_m_per_s) and self.a_m_per_s > 0, "calibration.a_m_per_s",
                f"must be a positive speed in m/s, got {self.a_m_per_s}",
                "pass the slope of path against time, about 3e8 m/s")
        b = np.array(self.b_m, dtype=np.float64).reshape(-1)
        require(bool(np.all(np.isfinite(b))), "calibration.b_m", "contains NaN or inf",
                "pass finite offsets in metres")
        b.flags.writeable = False
        object.__setattr__(self, "b_m", b)

    @classmethod
    def for_setup(cls, setup) -> "PathCalibration":
        """The exact line of a simulated `Setup`: a = c, b = -(2 d + c mu)."""
        offset = -(2.0 * setup.device_distance_m + SPEED_OF_LIGHT * setup.pulse.peak_delay_s)
        return cls(SPEED_OF_LIGHT, np.full(setup.n_detectors, offset))

    def offsets(self, n_detectors: int) -> np.ndarray:
        if self.b_m.size == 1:
            return np.full(n_detectors, float(self.b_m[0]))
        require(self.b_m.size == n_detectors, "calibration.b_m",
                f"has {self.b_m.size} offsets for {n_detectors} detectors",
                "pass one offset, or one per detector")
        return self.b_m


@dataclass(frozen=True)
class PathAxis:
    """Per detector d: bin k covers hidden paths [start_m[d] + k step_m[d], ... + step_m[d])."""

    start_m: np.ndarray  # (D,) hidden path at the start of bin 0
    step_m: np.ndarray  # (D,) hidden path per bin
    n_bins: int

    @classmethod
    def of(cls, time_axis: TimeAxis, calibration: PathCalibration, n_detectors: int) -> "PathAxis":
        a, b = calibration.a_m_per_s, calibration.offsets(n_detectors)
        return cls(a * time_axis.t0_s + b, np.full(n_detectors, a * time_axis.dt_s),
                   time_axis.n_bins)

    @property
    def centre0_m(self) -> np.ndarray:
        """(D,) hidden path at the centre of bin 0 (where the score kernel samples bin 0)."""
        return self.start_m + 0.5 * self.step_m

    @property
    def stop_m(self) -> np.ndarray:
        """(D,) hidden path at the end of the last bin."""
        return self.start_m + self.n_bins * self.step_m

    def centres(self) -> np.ndarray:
        """(D, n_bins) hidden path at every bin centre."""
        return self.centre0_m[:, None] + self.step_m[:, None] * np.arange(self.n_bins)[None, :]


def simulation_bin(tdc_bin_s: float, wanted_s: float = 10e-12) -> float:
    """The widest simulation bin, at most `wanted_s`, that divides a TDC bin a whole number of
    times (a 33 ps TDC: 8.25 ps), so photon counts sum whole simulation bins."""
    return tdc_bin_s / max(1, math.ceil(tdc_bin_s / wanted_s - 1e-9))


def default_time_axis(setup, dt_s: float = 1e-12, max_hidden_path_m: float = 18.0) -> TimeAxis:
    """A window from the first possible hidden-path arrival (r1 + r2 = 0) out to
    `max_hidden_path_m` of hidden path; the paper's 6 m x 6 m search area needs about 18 m.
    With 1 ps bins that is the 60,000-bin axis of the demo."""
    t0 = 2.0 * setup.device_distance_m / SPEED_OF_LIGHT
    n = int(math.ceil(max_hidden_path_m / (SPEED_OF_LIGHT * dt_s)))
    return TimeAxis(t0, dt_s, n)
