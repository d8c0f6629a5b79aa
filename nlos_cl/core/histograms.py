"""The container that travels the whole way: histograms with the `Layout` they belong to (time
axis, wall spots, laser spot, the calibration from arrival time to hidden path, the truth when
known). `Signals` on a device carry the same `Layout` without the data."""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .errors import require
from .paths import PathAxis, PathCalibration, TimeAxis


def _frozen(value, shape=None) -> np.ndarray:
    arr = np.array(value, dtype=np.float64)  # our own copy, read-only
    if shape is not None:
        arr = arr.reshape(shape)
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True)
class Layout:
    """What a set of histograms means, without the data: rows are detectors."""

    time_axis: TimeAxis
    detector_spots: np.ndarray  # (n_detectors, 3)
    laser_spot: np.ndarray  # (3,)
    calibration: PathCalibration
    truth: np.ndarray | None = None
    truths: np.ndarray | None = None  # (K, 3) every target's centre, where known

    @property
    def n_detectors(self) -> int:
        return self.detector_spots.shape[0]

    @property
    def shape(self) -> tuple[int, int]:
        return (self.n_detectors, self.time_axis.n_bins)

    def path_axis(self) -> PathAxis:
        return PathAxis.of(self.time_axis, self.calibration, self.n_detectors)


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
    truths: np.ndarray | None = field(default=None)  # (K, 3) every target's centre, if known

    def __post_init__(self):
        data = np.array(self.data, dtype=np.float64)
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
        self.calibration.offsets(data.shape[0])  # validates the per-detector offsets
        object.__setattr__(self, "data", _frozen(data))
        object.__setattr__(self, "detector_spots", _frozen(spots))
        object.__setattr__(self, "laser_spot", _frozen(self.laser_spot, 3))
        if self.truth is not None:
            object.__setattr__(self, "truth", _frozen(self.truth, 3))
        if self.truths is not None:
            object.__setattr__(self, "truths", _frozen(self.truths, (-1, 3)))

    @classmethod
    def from_layout(cls, data, layout: Layout) -> "HistogramSet":
        return cls(data, layout.time_axis, layout.detector_spots, layout.laser_spot,
                   layout.calibration, truth=layout.truth, truths=layout.truths)

    @property
    def layout(self) -> Layout:
        return Layout(self.time_axis, self.detector_spots, self.laser_spot, self.calibration,
                      self.truth, self.truths)

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

    def path_axis(self) -> PathAxis:
        return PathAxis.of(self.time_axis, self.calibration, self.n_detectors)

    def hidden_path_axis(self) -> np.ndarray:
        """(n_detectors, n_bins) hidden path length r1 + r2 at each bin centre."""
        return self.path_axis().centres()
