"""Working with measured histograms: path calibration (paper Eq. 26), background subtraction,
and a photon-counting detector model (Poisson counts, dark counts, ambient light, timing
jitter, TDC binning) to test with, next to the paper's white Gaussian noise."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import gaussian_filter1d

from .errors import require
from .histograms import HistogramSet, PathCalibration, TimeAxis
from .scene import SPEED_OF_LIGHT

PLANCK = 6.62607015e-34


# ---------------------------------------------------------------------------- calibration

@dataclass(frozen=True)
class CalibrationFit:
    """path = a t + b fitted to (known free-space path, measured peak time) pairs."""

    calibration: PathCalibration
    rmse_m: float
    r2: float
    n_pairs: int

    @property
    def speed_error(self) -> float:
        """Relative deviation of the fitted slope from c (the paper measures 0.67 %)."""
        return self.calibration.a_m_per_s / SPEED_OF_LIGHT - 1.0


def fit_calibration(paths_m, peak_times_s) -> CalibrationFit:
    """Least-squares line path = a t + b (paper Eq. 26: s = 29.7 cm/ns t - 1269.1 cm), with its
    RMSE and coefficient of determination R^2."""
    p = np.asarray(paths_m, dtype=np.float64).reshape(-1)
    t = np.asarray(peak_times_s, dtype=np.float64).reshape(-1)
    require(p.size == t.size, "calibration pairs", f"{p.size} paths but {t.size} times",
            "pass one measured peak time per known path")
    require(p.size >= 3, "calibration pairs", f"only {p.size} pairs",
            "measure the target at 3 or more distances")
    require(bool(np.all(np.isfinite(p)) and np.all(np.isfinite(t))), "calibration pairs",
            "contain NaN or inf", "drop the failed measurements")
    require(float(np.ptp(t)) > 0, "calibration pairs", "all peak times are equal",
            "measure at different distances")
    a, b = np.polyfit(t, p, 1)
    residual = p - (a * t + b)
    total = float(np.sum((p - p.mean()) ** 2))
    r2 = 1.0 - float(np.sum(residual ** 2)) / total if total > 0 else float("nan")
    require(a > 0, "calibration pairs", f"the fitted slope is {a:.4g} m/s (path must grow with "
            "time)", "check that paths and times are paired in the same order")
    return CalibrationFit(PathCalibration(float(a), [float(b)]),
                          float(np.sqrt(np.mean(residual ** 2))), r2, int(p.size))


def peak_times(histograms: HistogramSet) -> np.ndarray:
    """Time of each histogram's maximum (seconds), refined by a parabola through 3 bins."""
    data = histograms.data
    k = np.clip(np.argmax(data, axis=1), 1, data.shape[1] - 2)
    rows = np.arange(len(data))
    m, c, p = data[rows, k - 1], data[rows, k], data[rows, k + 1]
    curvature = m - 2 * c + p
    offset = np.where(curvature < 0, 0.5 * (m - p) / np.where(curvature < 0, curvature, 1), 0)
    return histograms.time_axis.centres()[k] + np.clip(offset, -0.5, 0.5) * histograms.time_axis.dt_s


def with_calibration(histograms: HistogramSet, calibration: PathCalibration) -> HistogramSet:
    calibration.offsets(histograms.n_detectors)  # one offset, or one per detector
    return replace(histograms, calibration=calibration)


# ---------------------------------------------------------------------------- background

def subtract_background(histograms: HistogramSet, background: HistogramSet, *,
                        negatives: str = "clip", floor: float = 0.0) -> HistogramSet:
    """Signal minus a capture without the target (or a reference frame), bin by bin.

    negatives: 'clip' sets bins below 0 to 0; 'floor' sets bins below `floor` to `floor`;
    'keep' keeps them (the filter and the scoring clip negatives anyway).
    """
    require(negatives in ("clip", "floor", "keep"), "negatives",
            f"must be 'clip', 'floor' or 'keep', got {negatives!r}", "pick one of the three")
    require(background.data.shape == histograms.data.shape, "background",
            f"has shape {background.data.shape}, the signal {histograms.data.shape}",
            "record the background with the same detectors and time axis")
    require(background.time_axis == histograms.time_axis, "background.time_axis",
            "differs from the signal's", "record both with the same TDC settings")
    require(bool(np.allclose(background.detector_spots, histograms.detector_spots)),
            "background.detector_spots", "differ from the signal's", "use the same spots")
    diff = histograms.data - background.data
    if negatives == "clip":
        diff = np.maximum(diff, 0.0)
    elif negatives == "floor":
        diff = np.maximum(diff, floor)
    return replace(histograms, data=diff, allow_negative=True)


# ---------------------------------------------------------------------------- photon counting

@dataclass(frozen=True)
class PhotonCounter:
    """A SPAD/SNSPD with a TDC: what it turns the returned power into.

    Expected counts per bin = (power x bin width / photon energy) x efficiency x pulses
    + (dark count rate + ambient rate) x bin width x pulses; the signal part is blurred by the
    timing jitter (Gaussian, sigma); bins are summed into TDC bins; each TDC bin is Poisson.
    Pile-up and dead time are not modelled (valid while counts per pulse stay << 1).
    """

    n_pulses: float = 80e6  # one second at 80 MHz
    efficiency: float = 0.8
    dark_count_rate_hz: float = 100.0
    ambient_rate_hz: float = 1e4
    jitter_s: float = 30e-12
    tdc_bin_s: float = 50e-12
    wavelength_m: float = 1530e-9

    def __post_init__(self):
        for name in ("n_pulses", "efficiency", "wavelength_m", "tdc_bin_s"):
            value = getattr(self, name)
            require(math.isfinite(value) and value > 0, f"photon_counter.{name}",
                    f"must be positive, got {value}", "pass a positive number")
        require(self.efficiency <= 1, "photon_counter.efficiency",
                f"must be at most 1, got {self.efficiency}", "pass a fraction, e.g. 0.8")
        for name in ("dark_count_rate_hz", "ambient_rate_hz", "jitter_s"):
            value = getattr(self, name)
            require(math.isfinite(value) and value >= 0, f"photon_counter.{name}",
                    f"must be >= 0, got {value}", "pass 0 to switch it off")

    def expected_counts(self, histograms: HistogramSet) -> HistogramSet:
        axis = histograms.time_axis
        ratio = self.tdc_bin_s / axis.dt_s
        group = int(round(ratio))
        require(group >= 1 and abs(ratio - group) < 1e-6 * max(ratio, 1),
                "photon_counter.tdc_bin_s",
                f"{self.tdc_bin_s:.4g} s is not a whole number of the data's {axis.dt_s:.4g} s "
                "bins", "simulate with a bin width that divides the TDC bin")
        photon = PLANCK * SPEED_OF_LIGHT / self.wavelength_m
        signal = np.maximum(histograms.data, 0.0) * axis.dt_s / photon
        if self.jitter_s > 0:
            signal = gaussian_filter1d(signal, self.jitter_s / axis.dt_s, axis=1, mode="constant")
        counts = (signal * self.efficiency
                  + (self.dark_count_rate_hz + self.ambient_rate_hz) * axis.dt_s) * self.n_pulses
        n_tdc = axis.n_bins // group
        counts = counts[:, :n_tdc * group].reshape(len(counts), n_tdc, group).sum(axis=2)
        tdc_axis = TimeAxis(axis.t0_s, axis.dt_s * group, n_tdc)
        return replace(histograms, data=counts, time_axis=tdc_axis, allow_negative=False)

    def counts(self, histograms: HistogramSet, seed: int = 0) -> HistogramSet:
        """Poisson photon counts (float64 array of integers), seeded."""
        require(isinstance(seed, (int, np.integer)) and seed >= 0, "seed",
                f"must be a non-negative integer, got {seed!r}", "pass e.g. 0")
        expected = self.expected_counts(histograms)
        drawn = np.random.default_rng(seed).poisson(expected.data).astype(np.float64)
        return replace(expected, data=drawn)
