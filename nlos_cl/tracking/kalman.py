"""Kalman filtering (predict, update, gate, RTS smoothing) and the measurements the
estimators give it. State (p, v) in R^2d, d = 2 (x, y on the search plane) or 3; the motion
model that gives F and Q is nlos_cl.tracking.motion.

Measurement noise R: the estimator's covariance where it gives one (the model estimator's
LocatedTarget.covariance), plus min_sigma_m^2 on the diagonal (float32 kernels and the model's
own error put a floor under any covariance); axes with an infinite or undefined variance (height
with collinear wall spots) are left out of the update: they are not measured. Where the
estimator gives no covariance (the paper's argmax) R = fallback_sigma_m^2 I: 0.05 m per axis by
default, the spread of the argmax's per-frame error at 10 dB on the paper's scene (mean error
0.062 m ~ 1.25 sigma for a 2D Gaussian). A plate the others partly hide adds its
`hidden_sd_m`^2 (the model estimator's diagnostics, nlos_cl.localization.model.policy.warm) on the
diagonal: fitted over its lit part, its centre is as uncertain as the hidden part is long, which
the data's covariance cannot say (it stays a few mm), so such a frame weighs as little as it
tells and the track follows its motion past the crossing instead of the gate shutting it out.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..core.stats import chi2_quantile


@dataclass(frozen=True)
class Measurement:
    """One located target as the filter sees it: the measured axes (indices into x, y, z) and
    their values and covariance."""

    axes: np.ndarray  # (m,) int
    z: np.ndarray  # (m,)
    R: np.ndarray  # (m, m)
    position: np.ndarray  # (3,) as located
    source: object = None  # the LocatedTarget
    merged: bool = False  # two fits on one spot, merged (nlos_cl.tracking.association)


def measurement(target, d: int, *, fallback_sigma_m: float, min_sigma_m: float,
                unseen_axis: int | None = None) -> Measurement:
    """A LocatedTarget as a measurement of the first d axes (see the module docstring); the
    axis collinear wall spots cannot see (unseen_axis: 2, z, for a line along x; 0, x, for a
    line along z; region.unseen_axis) is never measured."""
    pos = np.asarray(target.position, dtype=np.float64).reshape(3)
    cov = None if target.covariance is None else np.asarray(target.covariance, np.float64)
    if unseen_axis is not None and unseen_axis < d:
        cov = np.diag([fallback_sigma_m ** 2] * 3) if cov is None else cov.copy()
        a = unseen_axis
        cov[a, :], cov[:, a], cov[a, a] = 0.0, 0.0, np.inf
    if cov is None or cov.shape != (3, 3):
        axes = np.arange(d)
        R = fallback_sigma_m ** 2 * np.eye(d)
    else:
        diag = np.diag(cov)[:d]
        axes = np.flatnonzero(np.isfinite(diag) & (diag >= 0))
        block = cov[np.ix_(axes, axes)]
        if not np.all(np.isfinite(block)):  # correlations undefined: keep the variances
            block = np.diag(diag[axes])
        floor = min_sigma_m ** 2 + hidden_sd(target) ** 2
        R = 0.5 * (block + block.T) + floor * np.eye(len(axes))
    return Measurement(axes, pos[axes], R, pos, target)


def hidden_sd(target) -> float:
    """The model estimator's `hidden_sd_m` for this target (0 where it has none; the paper's
    argmax has no fit, and its tracker imports no model code)."""
    value = getattr(getattr(target, "fit", None), "hidden_sd_m", None)
    return float(value) if value is not None and math.isfinite(value) else 0.0


def predict(x, P, F, Q):
    return F @ x, F @ P @ F.T + Q


class Modes(NamedTuple):
    """An interacting multiple model's state (motion.Interacting): each mode's probability,
    state and covariance; `combined` is what the rest of the tracker sees."""

    mu: np.ndarray  # (M,)
    x: np.ndarray  # (M, n)
    P: np.ndarray  # (M, n, n)

    def combined(self):
        """(x, P): the mixture's mean and covariance (the modes' spread included)."""
        x = self.mu @ self.x
        d = self.x - x
        P = np.einsum("j,jab->ab", self.mu, self.P + d[:, :, None] * d[:, None, :])
        return x, 0.5 * (P + P.T)


class Prediction(NamedTuple):
    """A live track predicted to a frame's time (modes: each IMM mode's prediction, with the
    predicted mode probabilities; None under a single motion model)."""

    track: object
    x: np.ndarray
    P: np.ndarray
    modes: Modes | None = None


def predict_tracks(tracks, t: float, motion) -> list[Prediction]:
    """Every track's prediction to time t with the motion model (the tracks are unchanged):
    the Tracker makes them once per frame, for the warm prior and the filter alike."""
    out = []
    for tr in tracks:
        dt, d = t - tr.t_s, tr.dims
        F = motion.transition(dt, d)
        if not hasattr(motion, "switching"):
            out.append(Prediction(tr, *predict(tr.state, tr.covariance, F,
                                               motion.process_noise(dt, d))))
            continue
        modes = predict_modes(track_modes(tr, motion), F, motion.mode_noises(dt, d),
                              motion.switching(dt))
        out.append(Prediction(tr, *modes.combined(), modes))
    return out


def apply_prediction(p: Prediction, t: float) -> None:
    """The track moved to its prediction at time t (what a coasting track keeps, the predicted
    modes included), the prediction remembered for the smoother (`pending`)."""
    tr = p.track
    tr.pending = (t - tr.t_s, p.x, p.P)
    tr.state, tr.covariance, tr.t_s = p.x, p.P, t
    tr.modes = tr.predicted_modes = p.modes
    tr.modes_of = None if p.modes is None else (p.x.copy(), p.P.copy())


def update_track(track, m: Measurement) -> None:
    """The track updated with m: its modes under an IMM (the state is their mixture), else
    its state."""
    if track.modes is None:
        track.state, track.covariance = update(track.state, track.covariance, m)
        return
    track.modes = update_modes(track.modes, m)
    track.state, track.covariance = track.modes.combined()
    track.modes_of = (track.state.copy(), track.covariance.copy())


def track_modes(track, motion) -> Modes:
    """The track's IMM modes, or, where its state was set otherwise (a birth, a re-acquired
    track: nlos_cl.tracking.recovery), every mode at its state with the initial probabilities."""
    modes, made = track.modes, track.modes_of
    if modes is not None and np.array_equal(made[0], track.state) \
            and np.array_equal(made[1], track.covariance):
        return modes
    mu = np.asarray(motion.initial_modes, float)
    return Modes(mu, np.repeat(track.state[None], len(mu), axis=0),
                 np.repeat(track.covariance[None], len(mu), axis=0))


def predict_modes(modes: Modes, F, Q, switching) -> Modes:
    """The IMM's mixing and per-mode prediction: Q (M, n, n) each mode's process noise,
    switching (M, M) Pi[i, j] = P(j next | i now). Returns the predicted modes, whose mu are
    the predicted mode probabilities c_j = sum_i Pi[i, j] mu_i."""
    c = switching.T @ modes.mu
    w = switching * modes.mu[:, None] / c[None, :]  # w[i, j] = P(i now | j next)
    x0 = w.T @ modes.x
    d = modes.x[None, :, :] - x0[:, None, :]  # [j, i, :]
    P0 = np.einsum("ij,iab->jab", w, modes.P) + np.einsum("ij,jia,jib->jab", w, d, d)
    return Modes(c, x0 @ F.T, F @ P0 @ F.T + Q)


MODE_FLOOR = 1e-9  # no mode's probability falls to exactly 0 (it could never come back)


def _mode_innovations(modes: Modes, m: Measurement):
    """(y (M, k), S (M, k, k)) of every mode at once: the measured axes are a selection, so
    H P H^T is P's (axes, axes) block."""
    ax = m.axes
    return m.z[None, :] - modes.x[:, ax], modes.P[:, ax[:, None], ax[None, :]] + m.R[None]


def update_modes(pred: Modes, m: Measurement) -> Modes:
    """Each mode updated with m (the Kalman update in Joseph form, as `update`, batched over the
    modes); the mode probabilities by each mode's innovation likelihood."""
    if len(m.axes) == 0:
        return pred
    ax = m.axes
    y, S = _mode_innovations(pred, m)
    PHt = pred.P[:, :, ax]  # (M, n, k)
    # one batched solve: S^-1 y and S^-1 H P (= K^T, S and P symmetric)
    both = np.linalg.solve(S, np.concatenate([y[..., None], PHt.transpose(0, 2, 1)], axis=2))
    w, K = both[..., 0], both[..., 1:].transpose(0, 2, 1)  # K = P H^T S^-1
    logl = -0.5 * (np.einsum("ja,ja->j", y, w) + np.linalg.slogdet(S)[1])
    A = np.broadcast_to(np.eye(pred.x.shape[1]), pred.P.shape).copy()
    A[:, :, ax] -= K  # I - K H
    P = A @ pred.P @ A.transpose(0, 2, 1) + K @ m.R @ K.transpose(0, 2, 1)
    x = pred.x + np.einsum("jab,jb->ja", K, y)
    mu = pred.mu * np.exp(logl - logl.max())
    mu = np.maximum(mu / mu.sum(), MODE_FLOOR)
    return Modes(mu / mu.sum(), x, 0.5 * (P + P.transpose(0, 2, 1)))


def gate_distance2(x, P, modes: Modes | None, m: Measurement) -> float:
    """The squared Mahalanobis distance gates and assignments use: under an IMM (modes: the
    predicted ones), the nearest mode's (a turn is gated by the manoeuvring mode, not by the
    steady one that dominates the mixture); else the state's (x, P)."""
    if modes is None:
        return mahalanobis2(x, P, m)
    if len(m.axes) == 0:
        return math.inf
    y, S = _mode_innovations(modes, m)
    w = np.linalg.solve(S, y[..., None])[..., 0]  # batched: one solve for all the modes
    return float(np.min(np.einsum("ja,ja->j", y, w)))


def innovation(x, P, m: Measurement):
    """(y, S): the measurement's residual against the state, and its covariance."""
    d = len(x) // 2
    H = np.zeros((len(m.axes), 2 * d))
    H[np.arange(len(m.axes)), m.axes] = 1.0
    return m.z - H @ x, H @ P @ H.T + m.R, H


def mahalanobis2(x, P, m: Measurement) -> float:
    if len(m.axes) == 0:
        return math.inf
    y, S, _ = innovation(x, P, m)
    return float(y @ np.linalg.solve(S, y))


def update(x, P, m: Measurement):
    """The Kalman update (Joseph form: P stays symmetric and positive definite)."""
    if len(m.axes) == 0:
        return x, P
    y, S, H = innovation(x, P, m)
    K = np.linalg.solve(S, H @ P).T  # P H^T S^-1 (S, P symmetric)
    A = np.eye(len(x)) - K @ H
    P = A @ P @ A.T + K @ m.R @ K.T
    return x + K @ y, 0.5 * (P + P.T)


_GATES: dict = {}


def gate_threshold(probability: float, dof: int) -> float:
    """The chi-square quantile that a correct measurement's squared Mahalanobis distance stays
    under with `probability` (nlos_cl.core.stats, cached: a frame asks for the same few)."""
    key = (probability, dof)
    if key not in _GATES:
        _GATES[key] = chi2_quantile(probability, dof)
    return _GATES[key]


def rts_smooth(filtered, predicted):
    """Rauch-Tung-Striebel smoothing of one track, offline: `filtered` is [(x_k, P_k)] after
    each frame's update (or coast), `predicted` is [(F_k, x_k|k-1, P_k|k-1)] into each frame
    (None for the first). Returns [(x_k|N, P_k|N)]: every frame's state given all frames, the
    later ones included. Same model and noise as the filter, so no extra parameter."""
    xs, Ps = filtered[-1]
    out = [(xs, Ps)]
    for k in range(len(filtered) - 2, -1, -1):
        x, P = filtered[k]
        F, xp, Pp = predicted[k + 1]
        C = np.linalg.solve(Pp, F @ P).T  # P F^T Pp^-1 (P, Pp symmetric)
        xs, Ps = x + C @ (xs - xp), P + C @ (Ps - Pp) @ C.T
        Ps = 0.5 * (Ps + Ps.T)
        out.append((xs, Ps))
    return out[::-1]
