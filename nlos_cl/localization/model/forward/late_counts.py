"""The late copies (forward.late) under the counts' Poisson likelihood: the amplitudes of the
targets' columns and of their copies' budget columns (`late.capped`) and each detector's
background, all >= 0, that maximise the Poisson likelihood.

Why not the counts' Newton (forward.likelihood._poisson_newton): the copies are nearly
collinear (lobes 0.15 m apart of 0.1 m sd, tails of 50-400 ps), and its steps, kept off 0
only on their way down, ran up to amplitudes of 1e246 (a mismatch scene in counts: the
plate's cost 1e245 with the copies against 4,959 without). Here each step is the weighted
non-negative least squares of the counts on all the columns with weights 1 / lambda
(iteratively reweighted least squares, whose fixed point is the Poisson likelihood's
constrained maximum: the weighted normal equations there are its score equations), solved on
the normal equations (`gram_nnls`: Lawson and Hanson's active set, started from the last
step's), each step shortened until the likelihood does not fall.
"""
from __future__ import annotations

import numpy as np

from ....core.constants import TINY

ITERS = 60  # reweightings at most (from a cold start ~10-25 where measured)
TOL = 1e-9  # converged: the step moves the expected counts by under TOL of those observed


def loglik(y, valid, lam) -> float:
    lam = np.maximum(lam, 1e-300)
    return float(np.sum(valid * (np.where(y > 0, y * np.log(lam), 0.0) - lam)))


def gram_nnls(g, r, x0=None, iters: int = 200) -> np.ndarray:
    """argmin_{x >= 0} x'Gx - 2 x'r (G positive semi-definite), equilibrated; Lawson and
    Hanson's active set from the support of x0 (>= 0) where given."""
    scale = np.sqrt(np.maximum(np.diag(g), TINY))
    g, r = g / np.outer(scale, scale), r / scale
    m = len(r)
    x = np.zeros(m) if x0 is None else np.maximum(np.asarray(x0, float) * scale, 0.0)
    passive = x > 0
    x = _feasible(g, r, x, passive, m)
    for _ in range(iters):
        grad = r - g @ x
        cand = np.flatnonzero(~passive & (grad > 1e-12 * max(float(np.abs(r).max()), TINY)))
        if not cand.size:
            break
        passive[cand[np.argmax(grad[cand])]] = True
        x = _feasible(g, r, x, passive, m)
        passive = x > 0
    return x / scale


def _feasible(g, r, x, passive, m):
    """The least squares on the passive set, stepped back towards x (feasible) until every
    passive value stays > 0 (Lawson and Hanson's inner loop)."""
    for _ in range(3 * m + 1):
        if not passive.any():
            return np.zeros(m)
        z = np.zeros(m)
        idx = np.flatnonzero(passive)
        z[idx] = np.linalg.lstsq(g[np.ix_(idx, idx)], r[idx], rcond=None)[0]
        if np.all(z[idx] > 0):
            return z
        neg = passive & (z <= 0)
        alpha = np.min(x[neg] / np.maximum(x[neg] - z[neg], TINY))
        x = x + alpha * (z - x)
        passive = passive & (x > 1e-15 * max(float(x.max()), TINY))
        x[~passive] = 0.0
    return x


def solve(y, valid, columns, phi) -> np.ndarray:
    """[amplitudes (M,), backgrounds (D,)] >= 0 maximising the Poisson likelihood of counts
    y (D, n) for lambda = sum_m x_m columns_m + b_d on the valid bins, from phi (>= 0)."""
    m, (d, n) = len(columns), y.shape
    flat = columns.reshape(m, -1)
    yv = (y * valid).reshape(-1)
    total = float(yv.sum()) + 1.0
    scale = np.concatenate([flat @ valid.reshape(-1), valid.sum(axis=1)])
    phi = np.maximum(np.asarray(phi, float), 0.0)

    def lam_of(p):
        return (p[:m] @ flat).reshape(d, n) + p[m:, None] * valid

    lam = lam_of(phi)
    best = loglik(y, valid, lam)
    for _ in range(ITERS):
        w = valid / np.maximum(lam, 1e-9 * total / max(yv.size, 1) + 1e-12)
        aw = flat * w.reshape(-1)
        g = np.zeros((m + d, m + d))
        g[:m, :m] = aw @ flat.T
        g[:m, m:] = aw.reshape(m, d, n).sum(axis=2)
        g[m:, :m] = g[:m, m:].T
        g[m:, m:] = np.diag(w.sum(axis=1))
        rhs = np.concatenate([aw @ yv, (w * y).sum(axis=1)])
        new = gram_nnls(g, rhs, phi)
        for _ in range(30):  # shortened until the likelihood does not fall
            lam_new = lam_of(new)
            ll = loglik(y, valid, lam_new)
            if ll >= best - 1e-12 * abs(best):
                break
            new = 0.5 * (phi + new)
        else:
            break
        moved = np.abs(new - phi) * scale
        phi, lam, best = new, lam_new, max(ll, best)
        if np.all(moved <= TOL * total):
            break
    return phi
