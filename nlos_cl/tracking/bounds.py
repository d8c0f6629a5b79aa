"""How well could any causal tracker do? The Cramer-Rao bound on a target's x-y position at
each frame from the measurements up to that frame, for a target *known* to follow a path
family (a straight line at constant velocity, a circle at constant speed) measured with the
frames' own covariances.

A tracker that knows less (a constant-velocity Kalman filter whose process noise must allow
turns) does no better than this bound, so it says what a goal such as "the filter's RMS <=
0.5 x the per-frame RMS" asks of the motion alone. With 50 equal frames and the first 5 left
out, the straight line's bound is 0.42 x the per-frame error, a constant-speed circle's 0.51 x:
on a curve even a tracker that knows the target walks a circle cannot halve the error without
waiting for later frames (a fixed-lag smoother can: docs/tracking.md).

    from nlos_cl.tracking.bounds import causal_bound, line
    bound = causal_bound(line, (x0, y0, vx, vy), t_s, covariances)   # (F, 2, 2)
"""
from __future__ import annotations

import numpy as np

from ..core.errors import require


def line(params, t):
    """x-y positions (F, 2) at times t of a constant-velocity line: params (x0, y0, vx, vy)."""
    x0, y0, vx, vy = params
    return np.stack([x0 + vx * t, y0 + vy * t], axis=1)


def circle(params, t):
    """x-y positions (F, 2) at times t on a circle at constant speed: params (cx, cy, radius,
    phase, omega); the position is (cx + r sin(phase + omega t), cy - r cos(phase + omega t))."""
    cx, cy, r, phase, omega = params
    a = phase + omega * t
    return np.stack([cx + r * np.sin(a), cy - r * np.cos(a)], axis=1)


def _jacobian(path, params, t, step=1e-6):
    """d position / d params (F, 2, P) by central differences (exact for the line)."""
    params = np.asarray(params, dtype=np.float64)
    cols = []
    for i in range(len(params)):
        d = np.zeros_like(params)
        d[i] = step
        cols.append((path(params + d, t) - path(params - d, t)) / (2 * step))
    return np.stack(cols, axis=-1)


def causal_bound(path, params, t_s, covariances) -> np.ndarray:
    """(F, 2, 2): the bound on the x-y covariance of any unbiased estimate of frame k's
    position from frames 0..k. covariances (F, 2, 2): each frame's measurement covariance
    (NaN or inf where a frame has no measurement: it adds no information). Frames before the
    path's parameters are determined get an infinite bound."""
    t = np.asarray(t_s, dtype=np.float64)
    cov = np.asarray(covariances, dtype=np.float64)
    require(t.ndim == 1 and cov.shape == (len(t), 2, 2), "covariances",
            f"must be (F, 2, 2) for F = {len(t)} frame times, got {cov.shape}",
            "pass one 2 x 2 x-y covariance per frame")
    jac = _jacobian(path, params, t)
    n_params = jac.shape[-1]
    info = np.zeros((n_params, n_params))
    out = np.full((len(t), 2, 2), np.inf)
    for k in range(len(t)):
        if np.all(np.isfinite(cov[k])):
            info += jac[k].T @ np.linalg.solve(cov[k], jac[k])
        if np.linalg.matrix_rank(info) == n_params:
            out[k] = jac[k] @ np.linalg.solve(info, jac[k].T)
    return out
