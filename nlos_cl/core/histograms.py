"""The container that travels the whole way: histograms with the `Layout` they belong to (time
axis, wall spots, laser spot(s), the calibration from arrival time to hidden path, the truth
when known). `Signals` on a device carry the same `Layout` without the data.

Laser spots: one (3,) for every histogram (one laser, N detectors: the paper's layout), or one
per histogram, (N, 3) ("paired": each histogram its own laser and detection point; confocal
captures are paired with laser = detection point; N lasers and one detector is paired too).
`laser_spots` is always (N, 3)."""
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
    laser_spot: np.ndarray  # (3,), or (n_detectors, 3): each histogram's own (paired)
    calibration: PathCalibration
    truth: np.ndarray | None = None
    truths: np.ndarray | None = None  # (K, 3) every target's centre, where known

    @property
    def n_detectors(self) -> int:
        return self.detector_spots.shape[0]

    @property
    def paired(self) -> bool:
        """Does each histogram have its own laser spot?"""
        return np.ndim(self.laser_spot) == 2

    @property
    def laser_spots(self) -> np.ndarray:
        """(n_detectors, 3): each histogram's laser spot."""
        return laser_spots_of(self.laser_spot, self.n_detectors)

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
    laser_spot: np.ndarray  # (3,), or (n_detectors, 3): each histogram's own (paired)
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
        object.__setattr__(self, "laser_spot", _laser(self.laser_spot, data.shape[0]))
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

    paired = Layout.paired
    laser_spots = Layout.laser_spots

    def with_data(self, data) -> "HistogramSet":
        return replace(self, data=data)

    def select(self, rows) -> "HistogramSet":
        """The histograms of some detectors only (e.g. one detector's own probability map)."""
        rows = np.atleast_1d(np.asarray(rows, dtype=int))
        offsets = self.calibration.offsets(self.n_detectors)[rows]
        laser = self.laser_spot[rows] if self.paired else self.laser_spot
        return replace(self, data=self.data[rows], detector_spots=self.detector_spots[rows],
                       laser_spot=laser,
                       calibration=PathCalibration(self.calibration.a_m_per_s, offsets))

    def path_axis(self) -> PathAxis:
        return PathAxis.of(self.time_axis, self.calibration, self.n_detectors)

    def hidden_path_axis(self) -> np.ndarray:
        """(n_detectors, n_bins) hidden path length r1 + r2 at each bin centre."""
        return self.path_axis().centres()


def _laser(value, n: int) -> np.ndarray:
    """A laser spot (3,) for every histogram, or one per histogram (n, 3), frozen."""
    arr = np.array(value, dtype=np.float64)
    if arr.size == 3 and arr.ndim <= 1:
        return _frozen(arr, 3)
    require(arr.shape == (n, 3), "histograms.laser_spot", f"expected (3,) (one laser for every "
            f"histogram) or ({n}, 3) (one per histogram), got {arr.shape}",
            "pass one laser point, or one per histogram row")
    return _frozen(arr)


def laser_spots_of(laser_spot, n: int) -> np.ndarray:
    """(n, 3): the laser spot of each of n histograms."""
    laser = np.asarray(laser_spot, dtype=np.float64)
    return laser if laser.ndim == 2 else np.broadcast_to(laser, (n, 3))


def reciprocal(h: HistogramSet) -> HistogramSet:
    """A capture of N laser points and ONE detection point read by reciprocity as one laser
    (that point) and N detector spots (the laser points): the same paths, the same data."""
    require(np.allclose(h.detector_spots, h.detector_spots[0]), "capture",
            "has more than one detection point", "pass a scan with one detector")
    return HistogramSet(h.data, h.time_axis, h.laser_spots, h.detector_spots[0], h.calibration)
