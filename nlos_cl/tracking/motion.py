"""Motion models: how a track's state (p, v) in R^2d moves between frames. `MotionModel` is
what the Tracker needs of one; `ConstantVelocity` (white acceleration of spectral density
q = accel_sigma^2, m^2/s^3) gives over dt F = [[I, dt I], [0, I]] and
Q = q [[dt^3/3 I, dt^2/2 I], [dt^2/2 I, dt I]]."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..core.errors import require


class MotionModel(Protocol):
    dims: int | None  # 2, 3, or None (the tracker's grid decides)
    initial_speed_sigma: float  # m/s: a new track's velocity uncertainty

    def transition(self, dt: float, d: int) -> np.ndarray:
        """F (2d, 2d): the state after dt without noise."""

    def process_noise(self, dt: float, d: int) -> np.ndarray:
        """Q (2d, 2d): the covariance the motion adds over dt."""


MEMBERS = ("dims", "initial_speed_sigma", "transition", "process_noise")


@dataclass(frozen=True)
class ConstantVelocity:
    """The motion model. accel_sigma (m/s^2): how hard targets may change velocity (a walking
    person: ~0.5-1); dims: 2, 3, or None (3 when the tracker's grid has depth in z, else 2);
    initial_speed_sigma (m/s): the velocity uncertainty of a new track."""

    accel_sigma: float = 0.5
    dims: int | None = None
    initial_speed_sigma: float = 1.0

    def __post_init__(self):
        for name in ("accel_sigma", "initial_speed_sigma"):
            v = getattr(self, name)
            require(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                    and v > 0, f"motion.{name}", f"must be a positive number, got {v!r}",
                    "pass e.g. 0.5")
        require(self.dims in (None, 2, 3), "motion.dims", f"must be 2, 3 or None, got "
                f"{self.dims!r}", "pass 2 (the search plane) or 3")

    @staticmethod
    def transition(dt: float, d: int) -> np.ndarray:
        F = np.eye(2 * d)
        F[:d, d:] = dt * np.eye(d)
        return F

    def process_noise(self, dt: float, d: int) -> np.ndarray:
        q, eye = self.accel_sigma ** 2, np.eye(d)
        return q * np.block([[dt ** 3 / 3 * eye, dt ** 2 / 2 * eye],
                             [dt ** 2 / 2 * eye, dt * eye]])
