"""The container that travels the whole way: histograms with their time axis, the wall spots
they belong to, and the calibration that maps arrival time to hidden path length."""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from .errors import require
from .scene import SPEED_OF_LIGHT, Setup


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
    def for_setup(cls, setup: Setup) -> "PathCalibration":
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
class HistogramSet:
    """One histogram per detector spot, in watts (mean power per bin), on a shared time axis."""

    data: np.ndarray  # (n_detectors, n_bins), float64, W
    time_axis: TimeAxis
    detector_spots: np.ndarray  # (n_detectors, 3)
    laser_spot: np.ndarray  # (3,)
    calibration: PathCalibration
    truth: np.ndarray | None = field(default=None)
    allow_negative: bool = True  # noisy or background-subtracted data dip below zero

    def __post_init__(self):
        data = np.array(self.data, dtype=np.float64)  # own copy, read-only
        require(data.ndim == 2, "histograms.data",
                f"expected shape (n_detectors, n_bins), got {data.shape}",
                "pass a 2-D array, one row per detector")
        require(bool(np.all(np.isfinite(data))), "histograms.data",
                f"{int(np.size(data) - np.isfinite(data).sum())} bins are NaN or inf",
                "replace missing bins by 0 (or drop the detector) before locating")
        if not self.allow_negative:
            require(bool(np.all(data >= 0)), "histograms.data",
                    f"{int((data < 0).sum())} bins are negative, photon counts cannot be",
                    "clip or floor the data, or pass allow_negative=True for "
                    "background-subtracted data")
        require(data.shape[1] == self.time_axis.n_bins, "histograms.data",
                f"has {data.shape[1]} bins but time_axis.n_bins = {self.time_axis.n_bins}",
                "make the time axis match the data")
        spots = np.array(self.detector_spots, dtype=np.float64)
        require(spots.shape == (data.shape[0], 3), "histograms.detector_spots",
                f"expected shape ({data.shape[0]}, 3) for {data.shape[0]} histograms, "
                f"got {spots.shape}", "pass one wall spot per histogram row")
        laser = np.array(self.laser_spot, dtype=np.float64).reshape(3)
        self.calibration.offsets(data.shape[0])  # validates the per-detector offsets
        for arr in (data, spots, laser):
            arr.flags.writeable = False
        object.__setattr__(self, "data", data)
        object.__setattr__(self, "detector_spots", spots)
        object.__setattr__(self, "laser_spot", laser)
        if self.truth is not None:
            truth = np.array(self.truth, dtype=np.float64).reshape(3)
            truth.flags.writeable = False
            object.__setattr__(self, "truth", truth)

    @property
    def n_detectors(self) -> int:
        return self.data.shape[0]

    def with_data(self, data) -> "HistogramSet":
        return replace(self, data=data)

    def select(self, rows) -> "HistogramSet":
        """The histograms of some detectors only (e.g. one detector's own probability map)."""
        rows = np.atleast_1d(np.asarray(rows, dtype=int))
        offsets = self.calibration.offsets(self.n_detectors)[rows]
        return replace(self, data=self.data[rows], detector_spots=self.detector_spots[rows],
                       calibration=PathCalibration(self.calibration.a_m_per_s, offsets))

    def hidden_path_axis(self) -> np.ndarray:
        """(n_detectors, n_bins) hidden path length r1 + r2 at each bin centre."""
        b = self.calibration.offsets(self.n_detectors)
        return self.calibration.a_m_per_s * self.time_axis.centres()[None, :] + b[:, None]

    def score_axis(self) -> tuple[np.ndarray, np.ndarray]:
        """Per detector: hidden path at the centre of bin 0, and path per bin (m)."""
        a, axis = self.calibration.a_m_per_s, self.time_axis
        b = self.calibration.offsets(self.n_detectors)
        return a * (axis.t0_s + 0.5 * axis.dt_s) + b, np.full(self.n_detectors, a * axis.dt_s)


def default_time_axis(setup: Setup, dt_s: float = 1e-12, max_hidden_path_m: float = 18.0,
                      ) -> TimeAxis:
    """A window from the first possible hidden-path arrival (r1 + r2 = 0) out to
    `max_hidden_path_m` of hidden path; the paper's 6 m x 6 m search area needs about 18 m.
    With 1 ps bins that is the 60,000-bin axis of the demo."""
    t0 = 2.0 * setup.device_distance_m / SPEED_OF_LIGHT
    n = int(math.ceil(max_hidden_path_m / (SPEED_OF_LIGHT * dt_s)))
    return TimeAxis(t0, dt_s, n)


@dataclass(frozen=True)
class Grid:
    """A regular grid of candidate positions: cell centres origin + index * step, per axis.

    The default is the paper's search plane z = 0 with x in [0, 6] m and y in (0, 6] m, 1 cm step.
    """

    origin: tuple = (0.0, 0.01, 0.0)
    step: tuple = (0.01, 0.01, 0.01)
    shape: tuple = (601, 600, 1)  # (nx, ny, nz)

    def __post_init__(self):
        origin = tuple(float(v) for v in np.asarray(self.origin, dtype=np.float64).reshape(-1))
        step = tuple(float(v) for v in np.asarray(self.step, dtype=np.float64).reshape(-1))
        shape = tuple(int(v) for v in np.asarray(self.shape).reshape(-1))
        require(len(origin) == 3 and all(map(math.isfinite, origin)), "grid.origin",
                f"expected three finite coordinates, got {self.origin!r}", "pass (x0, y0, z0)")
        require(len(shape) == 3 and all(n >= 1 for n in shape), "grid.shape",
                f"needs at least one cell along each axis, got {self.shape!r}",
                "pass (nx, ny, nz) with every count >= 1 (nz = 1 for a plane)")
        require(len(step) == 3 and all(math.isfinite(s) and s > 0 for s in step), "grid.step",
                f"must be three positive cell sizes, got {self.step!r}",
                "pass positive steps in metres, e.g. (0.01, 0.01, 0.01)")
        require(origin[1] > 0, "grid.origin",
                f"the grid starts at y = {origin[1]} m, on or behind the wall",
                "search only the hidden area y > 0")
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "step", step)
        object.__setattr__(self, "shape", shape)

    @classmethod
    def from_ranges(cls, x=(0.0, 6.0), y=(0.01, 6.0), z=(0.0, 0.0), step_m: float = 0.01) -> "Grid":
        """Inclusive ranges per axis, all on one step. Inverted or empty ranges are errors."""
        origin, shape = [], []
        for name, (lo, hi) in zip("xyz", (x, y, z)):
            require(math.isfinite(lo) and math.isfinite(hi) and hi >= lo, f"grid.{name}",
                    f"range ({lo}, {hi}) is empty or inverted", "pass (low, high) with high >= low")
            origin.append(lo)
            shape.append(int(math.floor((hi - lo) / step_m + 1e-6)) + 1)
        return cls(tuple(origin), (step_m,) * 3, tuple(shape))

    @property
    def n_cells(self) -> int:
        return self.shape[0] * self.shape[1] * self.shape[2]

    def axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return tuple(o + s * np.arange(n) for o, s, n in zip(self.origin, self.step, self.shape))

    def cell_centres(self) -> np.ndarray:
        """(nz, ny, nx, 3) positions, matching the score map's memory layout."""
        x, y, z = self.axes()
        zz, yy, xx = np.meshgrid(z, y, x, indexing="ij")
        return np.stack([xx, yy, zz], axis=-1)
