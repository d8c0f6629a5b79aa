"""Warm starts for the model estimator inside the Tracker.

Where each of the K targets the estimator fits is followed by a confirmed track whose last
measurement was a plate fit, the next frame's fit starts from those plates moved to the tracks'
predicted positions (`ModelEstimator.estimate(scored, start=rows)`, nlos_cl.localization.model.warm): only
the final fit runs, ~30 model evaluations on the host instead of ~150 forward calls. Two
fallbacks to the cold (full) fit: the estimator's own (the warm fit misses the data: Birge
ratio above its 99.9 % point), and the tracker's (a warm-fitted position outside every start
track's gate: the fit found another basin, or the track is wrong; either way the frame is
fitted from its data alone). The Locator reaches the estimator through `StartedEstimator`,
which carries the frame's start rows; the estimator itself keeps no per-frame state.
"""
from __future__ import annotations

import numpy as np

from . import kalman

PLATE = "upright plate"


class StartedEstimator:
    """The estimator as the tracker's Locator calls it: `estimate(scored)` with this frame's
    `start` rows (None: a cold fit)."""

    def __init__(self, estimator):
        self.estimator, self.start = estimator, None

    def __getattr__(self, name):  # name, local, needs_only_paper_estimate, ...: the estimator's
        if name == "estimator":  # not set yet (copy, unpickling): no recursion
            raise AttributeError(name)
        return getattr(self.estimator, name)

    def estimate(self, scored):
        return self.estimator.estimate(scored, start=self.start)


def can_start(estimator) -> bool:
    """Does the tracker warm-start this estimator? The model estimator with a fixed number of
    targets (not 'auto') and plates allowed. K >= 2 targets start from K tracks' plates (the
    two-target crossing, docs/tracking.md: identities kept in 10 of 10 seeds warm, 9 of 10
    cold, at 0.19 s against 1.41 s a frame)."""
    if getattr(estimator, "name", None) != "model":
        return False  # (and the paper's tracker never imports nlos_cl.localization.model)
    from ..localization.model import ModelEstimator
    return isinstance(estimator, ModelEstimator) and isinstance(estimator.targets, int) \
        and estimator.closed is not True


def plate_of(measurement):
    """The fitted plate row (6,) behind a measurement, or None (another model, a merged pair,
    an estimator without parameters)."""
    details = getattr(measurement.source, "details", None) or {}
    if measurement.merged or details.get("model") != PLATE:
        return None
    return np.array(list(details["params"].values()), dtype=np.float64)


def predictions(tracks, t, motion, targets):
    """[(track, predicted state, predicted covariance)] of the confirmed tracks with a plate,
    if there are exactly `targets` of them (else None: no warm start)."""
    ready = [tr for tr in tracks if tr.status == "confirmed" and tr.plate is not None]
    if len(ready) != targets:
        return None
    out = []
    for tr in ready:
        dt, d = t - tr.t_s, tr.dims
        F = motion.transition(dt, d)
        out.append((tr, *kalman.predict(tr.state, tr.covariance, F,
                                        motion.process_noise(dt, d))))
    return out


def start_rows(predicted) -> np.ndarray:
    """The tracks' last plates, their centres moved to the predicted positions (z too where
    the track is 3D; a 2D track keeps the plate's own height)."""
    rows = []
    for tr, x, _ in predicted:
        row = tr.plate.copy()
        row[:tr.dims] = x[:tr.dims]
        rows.append(row)
    return np.array(rows)


def outside_gates(measurements, predicted, gate_probability) -> bool:
    """Is some warm-fitted measurement outside the gate of every start track?"""
    for m in measurements:
        if not (getattr(m.source, "details", None) or {}).get("warm_start", {}).get("used"):
            continue
        gate = kalman.gate_threshold(gate_probability, len(m.axes))
        if all(kalman.mahalanobis2(x, P, m) > gate for _, x, P in predicted):
            return True
    return False
