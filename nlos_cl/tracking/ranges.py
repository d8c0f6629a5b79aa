"""Range tracks: a sequence of ONE confocal spot (Keyhole imaging: laser and SPAD look through
one opening at one wall spot) cannot place a target, but its range from the spot is observed
each frame (nlos_cl.localization.ranges.confocal_range: the middle of the strongest return).
`track_ranges` follows that range with the tracker's own motion models (nlos_cl.tracking.motion
and kalman, one axis: the state is range and range rate), what `nlos-cl track` does for such a
file instead of refusing it.

Measurement noise: measured on the data as the tracker's argmax sigma is (tracking/scatter.py:
1.4826 MAD of second differences / sqrt(6)), over every frame given, never below `floor_m`
(the range one bin spans over sqrt(12), where the record's quantisation is the noise). On
Keyhole's letters (docs/results/real-data/real-data.md) the range's error against the stage is systematic (where
each letter's bright middle sits), not frame-to-frame noise (0.4-2.8 mm): filtering moves the
RMS by < 0.1 mm.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.errors import require
from ..localization.ranges import detected_range
from . import kalman
from .motion import Interacting
from .scatter import robust_sigma


@dataclass(frozen=True)
class RangePoint:
    """One frame of a range track: the filter's (or smoother's) range (m) from the spot, its sd,
    its rate (m/s), and the frame's own measured range (NaN where the frame's detection found
    no return: the filter coasts there; every value NaN before the first return)."""

    frame: int
    t_s: float
    range_m: float
    range_sd_m: float
    speed_m_s: float
    measured_m: float


def range_floor(time_axis) -> float:
    """The least range noise a record can show (m): one bin's range (half its path) over
    sqrt(12), its quantisation."""
    return 0.5 * float(time_axis.dt_s) * SPEED_OF_LIGHT / math.sqrt(12.0)


def range_sigma(measured, floor_m: float) -> float:
    """The measured ranges' frame-to-frame noise (m; module docstring), never below floor_m."""
    x = np.asarray(measured, np.float64)
    second = np.diff(x, 2) if len(x) >= 3 else np.zeros(0)
    return robust_sigma(second[np.isfinite(second)][:, None], floor_m)


@dataclass(frozen=True)
class RangeStep:
    """One frame's measurement: the frame read (its index, t_s and histograms) and its
    detected range (m; NaN where the frame's detection found no return)."""

    frame: object
    range_m: float


def frame_ranges(frames, h_s: float | None = None, *, backend=None):
    """Each frame's detected_range, a RangeStep per frame as the frames come (lazily, so that
    whoever iterates knows which frame a warning comes from: `nlos-cl track` names it)."""
    for frame in frames:
        yield RangeStep(frame, detected_range(frame.histograms, h_s, backend=backend)[0])


def track_steps(steps, *, motion=None, smooth: bool = False) -> tuple[list, float]:
    """(RangePoints, the measurement sd) of RangeSteps (frame_ranges, in time order):
    range_sigma over them all, then track_ranges. No step with a return: ([], nan)."""
    steps = list(steps)
    require(bool(steps), "frames", "is empty", "pass at least one frame")
    measured = [s.range_m for s in steps]
    if not np.isfinite(measured).any():
        return [], float("nan")
    sigma = range_sigma(measured, range_floor(steps[-1].frame.histograms.time_axis))
    return track_ranges(measured, [s.frame.t_s for s in steps], motion=motion, sigma_m=sigma,
                        smooth=smooth), sigma


def track_frames(frames, *, h_s: float | None = None, motion=None, smooth: bool = False, backend=None
                 ) -> tuple[list, float]:
    """(RangePoints, the measurement sd) of sequence frames (SequenceFrames of one confocal
    spot, in time order): each frame's detected_range (NaN: no return), range_sigma over them
    all, then track_ranges: what `nlos-cl track` does with such a file. No frame with a return:
    ([], nan)."""
    return track_steps(frame_ranges(frames, h_s, backend=backend), motion=motion, smooth=smooth)


def track_ranges(measured, times_s, *, motion=None, sigma_m: float, smooth: bool = False
                 ) -> list[RangePoint]:
    """The causal filter's range per frame (or, smooth=True, the RTS smoother's), from the
    measured ranges (m) at times_s (s, increasing); motion: the Tracker's models (default
    Interacting()); sigma_m: the measurement sd (range_sigma). A NaN range (no return that
    frame) is coasted over; frames before the first return have NaN states."""
    z, t = np.asarray(measured, np.float64), np.asarray(times_s, np.float64)
    require(z.ndim == 1 and z.shape == t.shape and len(z) >= 1, "measured",
            f"must be one range per frame time, got {z.shape} ranges for {t.shape} times",
            "pass as many ranges as frame times")
    require(bool(np.all(np.diff(t) > 0)), "times_s", "must increase from frame to frame",
            "pass the frames' timestamps in order")
    require(math.isfinite(sigma_m) and sigma_m > 0, "sigma_m",
            f"must be a positive number of metres, got {sigma_m!r}", "pass range_sigma(...)")
    require(bool(np.isfinite(z).any()), "measured", "holds no range (no frame has a return)",
            "pass at least one measured range")
    motion = Interacting() if motion is None else motion
    first = int(np.argmax(np.isfinite(z)))
    R = np.array([[sigma_m ** 2]])
    x = np.array([z[first], 0.0])
    P = np.diag([sigma_m ** 2, motion.initial_speed_sigma ** 2])
    modes = None
    if hasattr(motion, "switching"):
        mu = np.asarray(motion.initial_modes, float)
        modes = kalman.Modes(mu, np.repeat(x[None], len(mu), 0), np.repeat(P[None], len(mu), 0))
    filtered, predicted = [(x, P)], [None]
    for k in range(first + 1, len(z)):
        dt = float(t[k] - t[k - 1])
        F = motion.transition(dt, 1)
        seen = bool(np.isfinite(z[k]))  # else a coast: the prediction stands
        m = kalman.Measurement(np.array([0]), z[k:k + 1], R, np.array([z[k], 0.0, 0.0]))
        if modes is None:
            xp, Pp = kalman.predict(x, P, F, motion.process_noise(dt, 1))
            x, P = kalman.update(xp, Pp, m) if seen else (xp, Pp)
        else:
            pred = kalman.predict_modes(modes, F, motion.mode_noises(dt, 1), motion.switching(dt))
            xp, Pp = pred.combined()
            modes = kalman.update_modes(pred, m) if seen else pred
            x, P = modes.combined()
        filtered.append((x, P))
        predicted.append((F, xp, Pp))
    states = kalman.rts_smooth(filtered, predicted) if smooth else filtered
    nan = float("nan")
    return [RangePoint(k, float(t[k]), nan, nan, nan, float(z[k])) for k in range(first)] + [
        RangePoint(k, float(t[k]), float(s[0]), math.sqrt(max(float(c[0, 0]), 0.0)),
                   float(s[1]), float(z[k])) for k, (s, c) in enumerate(states, start=first)]
