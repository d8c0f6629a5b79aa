"""Sensor noise of a fixed absolute level, for sequences with static clutter.

nl.AWGN is "measured" noise: its power follows each frame's own signal (MATLAB's awgn(x, snr,
'measured'), as the paper uses it for single frames). In a stream that is not what a sensor
does: its noise floor (read-out, dark and ambient light) does not grow because a bright box
stands in the room. `SensorNoise` draws white Gaussian noise of a fixed sigma per detector,
whatever the scene holds; `SensorNoise.from_snr(signals, snr_db)` takes that sigma from a
reference frame (e.g. the target-only scene) at the level nl.AWGN would give it, and keeps it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import require


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
        from ..noise import check_seed
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
