"""The late copies (forward.late) under the counts' Poisson likelihood: the amplitudes of the
targets' columns and of their copies' budget columns (`late.capped`) and each detector's
background, all >= 0, that maximise the Poisson likelihood.

Why not the counts' Newton (forward.likelihood._poisson_newton): the copies are nearly
collinear (lobes 0.15 m apart of 0.1 m sd, tails of 50-400 ps), and its steps, kept off 0
only on their way down, ran up to amplitudes of 1e246 (a mismatch scene in counts: the
plate's cost 1e245 with the copies against 4,959 without). Here each step is the non-negative
maximum of the likelihood's quadratic model on all the columns (`solve`: Newton's Hessian, or
Fisher scoring's, i.e. iteratively reweighted least squares with weights 1 / lambda, where
Newton's step had to be shortened far from the optimum), solved on the normal equations
(`gram_nnls`: Lawson and Hanson's active set, started from the last step's), each step
shortened until the likelihood does not fall.
"""
from __future__ import annotations

import numpy as np

from ....core.constants import TINY

ITERS = 60  # steps at most (Newton's: median 3, at most 22, on CC-SOCR's solves)
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
    y (D, n) for lambda = sum_m x_m columns_m + b_d on the valid bins, from phi (>= 0).
    Each step is the constrained maximum of the likelihood's quadratic model (`gram_nnls`)
    with Newton's Hessian (weights y / lambda^2), or Fisher scoring's (1 / lambda) where the
    Newton step had to be shortened, whichever gains more; each shortened until the
    likelihood does not fall. Fisher scoring alone converged linearly where the model misses
    the data (its Hessian is Newton's only where y = lambda): CC-SOCR's 12 points as one laser
    took 53 steps a solve (median; 35 % stopped at ITERS), Newton 3, at the same optimum."""
    p = _Poisson(y, valid, columns)
    phi = np.maximum(np.asarray(phi, float), 0.0)
    lam = p.lam(phi)
    best = p.loglik(lam)
    for _ in range(ITERS):
        lamc = np.maximum(lam, p.floor)
        r = p.vf * (p.yf / lamc - 1.0)
        grad = np.concatenate([p.flat @ r, r.reshape(p.d, p.n).sum(axis=1)])
        took = None
        for w in (p.vf * p.yf / lamc ** 2, p.vf / lamc):  # Newton, then Fisher scoring
            step = _shortened(p, p.gram(w), grad, phi, best)
            if step is not None and (took is None or step[2] > took[2]):
                took = step
            if took is not None and took[3] == 0:  # a full step: no need for the other
                break
        if took is None:
            break
        new, lam_new, ll, _ = took
        moved = np.abs(new - phi) * p.scale
        gain = ll - best
        phi, lam, best = new, lam_new, max(ll, best)
        if np.all(moved <= TOL * p.total) or gain <= 1e-12 * abs(best):
            break
    return phi


def _shortened(p, g, grad, phi, best):
    """(x, lambda, loglik, halvings) of the quadratic model's constrained maximum from phi,
    halved towards phi until the likelihood does not fall below `best`; None if it does."""
    new = gram_nnls(g, grad + g @ phi, phi)
    for halved in range(30):
        lam_new = p.lam(new)
        ll = p.loglik(lam_new)
        if ll >= best - 1e-12 * abs(best):
            return new, lam_new, ll, halved
        new = 0.5 * (phi + new)
    return None


class _Poisson:
    """One solve's data, flattened: columns (M, D*n), valid and counts (D*n,)."""

    def __init__(self, y, valid, columns):
        self.m, (self.d, self.n) = len(columns), y.shape
        self.flat = columns.reshape(self.m, -1)
        self.vf, self.yf = valid.reshape(-1), (y * valid).reshape(-1)
        self.total = float(self.yf.sum()) + 1.0
        self.floor = 1e-9 * self.total / max(self.yf.size, 1) + 1e-12
        self.scale = np.concatenate([self.flat @ self.vf, valid.sum(axis=1)])
        self.pos = self.yf > 0

    def lam(self, x) -> np.ndarray:
        return x[:self.m] @ self.flat + np.repeat(x[self.m:], self.n) * self.vf

    def loglik(self, lam) -> float:
        return float(np.dot(self.yf[self.pos], np.log(np.maximum(lam[self.pos], 1e-300)))
                     - np.dot(self.vf, lam))

    def gram(self, w) -> np.ndarray:
        """[columns; one row per detector's background] weighted by w: their Gram matrix."""
        m, d, n = self.m, self.d, self.n
        aw = self.flat * w
        g = np.empty((m + d, m + d))
        g[:m, :m] = aw @ self.flat.T
        g[:m, m:] = aw.reshape(m, d, n).sum(axis=2)
        g[m:, :m] = g[:m, m:].T
        g[m:, m:] = np.diag(w.reshape(d, n).sum(axis=1))
        return g
