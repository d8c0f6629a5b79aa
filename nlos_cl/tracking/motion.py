"""Motion models: how a track's state (p, v) in R^2d moves between frames. `MotionModel` is
what the Tracker needs of one; `ConstantVelocity` (white acceleration of spectral density
q = accel_sigma^2, m^2/s^3) gives over dt F = [[I, dt I], [0, I]] and
Q = q [[dt^3/3 I, dt^2/2 I], [dt^2/2 I, dt I]].

`Interacting` (the Tracker's default) is an interacting multiple model (IMM; Blom &
Bar-Shalom 1988; Bar-Shalom, Li & Kirubarajan 2001, sec. 11.6) of constant-velocity modes that
differ only in their process noise: a steady mode (0.05 m/s^2: a walker between turns) and a
manoeuvring one (0.5 m/s^2, the single model's default), with Markov switching between them.
One process noise cannot serve both: on white 8 mm errors the filter's RMS over the per-frame
RMS is 0.47 on a straight path at accel_sigma 0.005 but 1.45 on a curve, whose best, 0.75,
needs 0.07-0.1 (docs/tracking.md, whose synthetic table has the IMM's 0.52 / 0.83). The
filter itself is nlos_cl.tracking.kalman (predict_modes, update_modes)."""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..core.errors import require


class MotionModel(Protocol):
    @property
    def dims(self) -> int | None:
        """2, 3, or None (the tracker's grid decides)."""

    @property
    def initial_speed_sigma(self) -> float:
        """m/s: a new track's velocity uncertainty."""

    def transition(self, dt: float, d: int) -> np.ndarray:
        """F (2d, 2d): the state after dt without noise."""

    def process_noise(self, dt: float, d: int) -> np.ndarray:
        """Q (2d, 2d): the covariance the motion adds over dt."""


MEMBERS = ("dims", "initial_speed_sigma", "transition", "process_noise")


def _check_dims(dims) -> None:
    require(dims in (None, 2, 3), "motion.dims", f"must be 2, 3 or None, got {dims!r}",
            "pass 2 (the search plane) or 3")


def _positive(owner: str, name: str, v, example) -> None:
    require(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            and v > 0, f"{owner}.{name}", f"must be a positive number, got {v!r}",
            f"pass e.g. {example}")


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
            _positive("motion", name, getattr(self, name), 0.5)
        _check_dims(self.dims)

    @staticmethod
    def transition(dt: float, d: int) -> np.ndarray:
        F = np.eye(2 * d)
        F[:d, d:] = dt * np.eye(d)
        return F

    def process_noise(self, dt: float, d: int) -> np.ndarray:
        return _white_acceleration(self.accel_sigma ** 2, float(dt), int(d))


@dataclass(frozen=True)
class Interacting:
    """An IMM of constant-velocity modes (see the module docstring). accel_sigmas (m/s^2): each
    mode's white acceleration, steady first; stay_s (s): how long a target stays in each mode on
    average (the Markov switching: over dt a mode is left with probability 1 - exp(-dt / stay),
    into the others evenly); dims and initial_speed_sigma as ConstantVelocity's. A new track
    starts with the mode probabilities stay_s / sum(stay_s) (the switching's stationary ones
    as dt -> 0).

    Defaults: steady 0.05 m/s^2 for 10 s, manoeuvring 0.5 m/s^2 for 0.5 s. On simulated 1-D
    tracks at 14 frames/s, 0.05-0.2 m white errors (/tmp study, 500 frames): a still or slowly
    walking target as smooth as a single model at 0.1 m/s^2 (RMS 0.060-0.074 m, 0.5 m/s^2:
    0.092-0.102 at 0.2 m errors), and a 1 m/s reversal followed better than either single
    model (RMS 0.066 m against 0.080 at 0.1 and 0.5 m/s^2)."""

    accel_sigmas: tuple = (0.05, 0.5)
    stay_s: tuple = (10.0, 0.5)
    dims: int | None = None
    initial_speed_sigma: float = 1.0

    def __post_init__(self):
        for name in ("accel_sigmas", "stay_s"):
            v = getattr(self, name)
            require(isinstance(v, (tuple, list)) and len(v) >= 2, f"motion.{name}",
                    f"must be a tuple of one value per mode (2 or more), got {v!r}",
                    "pass e.g. (0.05, 0.5)")
            for x in v:
                _positive("motion", name, x, "(0.05, 0.5)")
        require(len(self.accel_sigmas) == len(self.stay_s), "motion.stay_s",
                f"must have one value per mode ({len(self.accel_sigmas)}), got "
                f"{len(self.stay_s)}", "pass as many stay_s as accel_sigmas")
        _positive("motion", "initial_speed_sigma", self.initial_speed_sigma, 1.0)
        _check_dims(self.dims)

    transition = staticmethod(ConstantVelocity.transition)

    def process_noise(self, dt: float, d: int) -> np.ndarray:
        """The manoeuvring mode's Q: where one model stands for all (a re-acquisition
        candidate's filter, nlos_cl.tracking.recovery), the loosest."""
        return _white_acceleration(max(self.accel_sigmas) ** 2, float(dt), int(d))

    def mode_noises(self, dt: float, d: int) -> np.ndarray:
        """(M, 2d, 2d): each mode's Q over dt (read-only: cached, frames share their dt)."""
        return _mode_noises(tuple(a ** 2 for a in self.accel_sigmas), float(dt), int(d))

    def switching(self, dt: float) -> np.ndarray:
        """(M, M): Pi[i, j] = P(mode j after dt | mode i now) (read-only, cached)."""
        return _switching(tuple(self.stay_s), float(dt))

    @property
    def initial_modes(self) -> np.ndarray:
        stay = np.asarray(self.stay_s, float)
        return stay / stay.sum()


# Q and Pi depend on dt alone and a stream's frames share it: cached (np.block's Q cost 0.14 ms
# a call, an IMM frame needed three; read-only, so no caller can change a cached one)
@functools.lru_cache(maxsize=256)
def _white_acceleration(q: float, dt: float, d: int) -> np.ndarray:
    block = np.array([[dt ** 3 / 3, dt ** 2 / 2], [dt ** 2 / 2, dt]])
    out = q * np.kron(block, np.eye(d))
    out.flags.writeable = False
    return out


@functools.lru_cache(maxsize=256)
def _mode_noises(qs: tuple, dt: float, d: int) -> np.ndarray:
    out = np.stack([_white_acceleration(q, dt, d) for q in qs])
    out.flags.writeable = False
    return out


@functools.lru_cache(maxsize=256)
def _switching(stay_s: tuple, dt: float) -> np.ndarray:
    m = len(stay_s)
    leave = np.array([-math.expm1(-dt / s) for s in stay_s])
    pi = np.repeat((leave / (m - 1))[:, None], m, axis=1)
    np.fill_diagonal(pi, 1.0 - leave)
    pi.flags.writeable = False
    return pi
