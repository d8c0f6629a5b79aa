"""Noise models: each has `apply(signals, seed) -> Signals` on any backend, so the pipeline, the
tests and the studies treat them alike. White Gaussian noise (the paper's) runs on the device;
the photon counter (nlos_cl.measured.PhotonCounter) draws Poisson counts on the host."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .errors import require


class NoiseModel(Protocol):
    def apply(self, signals, seed: int): ...


def check_seed(seed) -> int:
    require(isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and seed >= 0,
            "seed", f"must be a non-negative integer, got {seed!r}", "pass e.g. 0")
    return int(seed)


@dataclass(frozen=True)
class AWGN:
    """Additive white Gaussian noise, snr_db below each histogram's measured power (mean of
    squares over the whole record, as MATLAB's awgn(x, snr, 'measured')), seeded."""

    snr_db: float = 10.0

    def __post_init__(self):
        require(isinstance(self.snr_db, (int, float)) and math.isfinite(self.snr_db), "snr_db",
                f"must be a finite number of decibels, got {self.snr_db!r}", "pass e.g. 10")

    def apply(self, signals, seed: int = 0):
        be = signals.backend
        normal = be.standard_normal(signals.shape, check_seed(seed))
        return signals.derive(be.call("add_awgn", signals.handle, normal, float(self.snr_db)))
