"""Noise models: each has `apply(signals, seed) -> Signals` on the signals' own backend, so the
pipeline, the tests, the studies and the tracker treat them alike.

- `AWGN`: the paper's white Gaussian noise, "measured" (its power follows each frame's own
  signal, as MATLAB's awgn(x, snr, 'measured')); drawn on the device.
- `SensorNoise`: white Gaussian noise of a fixed sigma per detector, for streams: a sensor's
  noise floor (read-out, dark and ambient light) does not grow because a bright box stands in
  the room. `SensorNoise.from_snr(signals, snr_db)` takes the sigma nl.AWGN would give a
  reference frame (e.g. the target-only scene) and keeps it.
- `PhotonCounter`: a SPAD/SNSPD with a TDC (Poisson counts, dark counts, ambient light, timing
  jitter, TDC binning), drawn on the host."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from ..core.constants import DEFAULT_JITTER_S, SPEED_OF_LIGHT
from ..core.errors import require
from ..core.histograms import HistogramSet, TimeAxis


class NoiseModel(Protocol):
    def apply(self, signals, seed: int): ...


def check_seed(seed) -> int:
    require(bool(isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and seed >= 0),
            "seed", f"must be a non-negative integer, got {seed!r}", "pass e.g. 0")
    return int(seed)


@dataclass(frozen=True)
class AWGN:
    """Additive white Gaussian noise, snr_db below each histogram's measured power (mean of
    squares over the whole record, as MATLAB's awgn(x, snr, 'measured')), seeded."""

    snr_db: float = 10.0

    def __post_init__(self):
        require(isinstance(self.snr_db, (int, float)) and not isinstance(self.snr_db, bool)
                and math.isfinite(self.snr_db) and -100.0 <= self.snr_db <= 200.0, "snr_db",
                f"must be a number of decibels in [-100, 200] (a noise 10^10 times the signal "
                f"to 10^-20 of it), got {self.snr_db!r}", "pass e.g. 10")

    def apply(self, signals, seed: int = 0):
        be = signals.backend
        normal = be.standard_normal(signals.shape, check_seed(seed))
        return signals.derive(be.call("add_awgn", signals.handle, normal, float(self.snr_db)))


@dataclass(frozen=True)
class SensorNoise:
    """White Gaussian noise, sigma_w watts per bin: one value for every detector, or one per
    detector. `apply(signals, seed) -> Signals` like the library's noise models (seeded)."""

    sigma_w: object  # float or a sequence, one per detector

    def __post_init__(self):
        s = np.atleast_1d(np.asarray(self.sigma_w, dtype=np.float64)) if _numeric(
            self.sigma_w) else None
        require(s is not None and s.ndim == 1 and len(s) >= 1 and np.all(np.isfinite(s))
                and np.all(s >= 0), "sigma_w", f"must be a non-negative number of watts (or "
                f"one per detector), got {self.sigma_w!r}", "pass e.g. SensorNoise.from_snr("
                "target_only_signals, 10)")
        object.__setattr__(self, "sigma_w", tuple(float(v) for v in s))

    @classmethod
    def from_snr(cls, signals, snr_db: float) -> "SensorNoise":
        """The sigma nl.AWGN(snr_db) would draw for `signals` (a HistogramSet or Signals):
        each detector's mean power over the record / 10^(snr_db / 10), then held fixed."""
        require(isinstance(snr_db, (int, float)) and not isinstance(snr_db, bool)
                and math.isfinite(snr_db), "snr_db", f"must be a finite number of decibels, "
                f"got {snr_db!r}", "pass e.g. 10")
        data = signals.histograms().data if hasattr(signals, "histograms") else signals.data
        power = np.mean(np.square(np.asarray(data, np.float64)), axis=1)
        return cls(tuple(np.sqrt(power / 10 ** (snr_db / 10))))

    def apply(self, signals, seed: int = 0):
        sigma = np.asarray(self.sigma_w)
        require(len(sigma) in (1, signals.n_detectors), "sigma_w", f"has {len(sigma)} values "
                f"for {signals.n_detectors} detectors", "pass one value, or one per detector")
        be = signals.backend
        # drawn on the host (a frame is small); in the signals' own units, scale_w W each
        normal = np.random.default_rng(check_seed(seed)).standard_normal(signals.shape)
        data = be.to_numpy(signals.handle) + normal * (sigma[:, None] / signals.scale_w)
        return signals.derive(be.from_numpy(data.astype(np.float32)))


def _numeric(value) -> bool:
    try:
        return np.asarray(value).dtype.kind in "iuf"
    except (TypeError, ValueError):
        return False


PLANCK = 6.62607015e-34


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
    jitter_s: float = DEFAULT_JITTER_S
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
            signal = _jitter(signal, self.jitter_s / axis.dt_s, axis)
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

    def apply(self, signals, seed: int = 0):
        """The noise-model interface (physics.noise): counts of `signals` (in watts) as Signals
        on the same backend, on the TDC's time axis. Drawn on the host (NumPy's Poisson)."""
        return signals.with_histograms(self.counts(signals.histograms(), seed))


_DIRECT_RADIUS = 256  # taps each side up to which the direct convolution is the faster


def _jitter(signal: np.ndarray, sigma_bins: float, axis: TimeAxis) -> np.ndarray:
    """Blur each row by a Gaussian of sigma_bins, truncated at 4 sigma and zero outside the axis
    (scipy's gaussian_filter1d, mode="constant"). A jitter longer than the whole window is
    refused (every bin would see a flat part of it); a long one is convolved by FFT, so the cost
    is ~n log n however long it is, not n x 8 sigma."""
    require(sigma_bins <= axis.n_bins, "photon_counter.jitter_s",
            f"{sigma_bins * axis.dt_s:.3g} s is longer than the whole {axis.n_bins} bin time axis "
            f"({axis.n_bins * axis.dt_s:.3g} s)", "pass a jitter shorter than the window, e.g. "
            "30e-12, or 0 to switch it off")
    radius = int(4.0 * sigma_bins + 0.5)
    if radius <= _DIRECT_RADIUS:
        from scipy.ndimage import gaussian_filter1d
        return gaussian_filter1d(signal, sigma_bins, axis=1, mode="constant")
    from scipy.signal import fftconvolve
    reach = min(radius, signal.shape[1] - 1)  # taps farther than the axis is long meet only 0
    x = np.arange(-reach, reach + 1)
    taps = np.exp(-0.5 * (x / sigma_bins) ** 2)
    # scipy normalises over all 2 radius + 1 taps: for sigma > 64 bins that sum is the
    # integral of the Gaussian over [-radius - 1/2, radius + 1/2] to ~1e-12
    taps /= (math.sqrt(2 * math.pi) * sigma_bins
             * math.erf((radius + 0.5) / (math.sqrt(2) * sigma_bins)))
    return fftconvolve(signal, taps[None, :], mode="same", axes=1)
