"""The instrument response measured on the direct return: an exponentially modified Gaussian
(a Gaussian of sigma convolved with an exponential tail of time constant tau, the usual shape
of a SPAD's timing response: jitter plus carrier diffusion) fitted to the aligned profile.

NumPy only (a one-shot `nlos-cl locate` does not load SciPy): Levenberg-Marquardt with a
numerical Jacobian on five parameters. The density is written as
exp(-(t - mu)^2 / 2 sigma^2) erfcx(z) / (2 tau), which neither overflows nor loses the tail.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...core.constants import TINY

_ERFC = np.vectorize(math.erfc, otypes=[np.float64])


def _erfcx(z: np.ndarray) -> np.ndarray:
    """exp(z^2) erfc(z): directly below 5, the asymptotic series (error < 2e-5) above."""
    z = np.asarray(z, dtype=np.float64)
    low = np.minimum(z, 5.0)
    out = np.exp(low * low) * _ERFC(low)
    big = z > 5.0
    if np.any(big):
        w = 1.0 / (z[big] * z[big])
        out[big] = (1 - w / 2 + 0.75 * w * w - 1.875 * w ** 3) / (z[big] * math.sqrt(math.pi))
    return out


def exgauss(t, area, mu, sigma, tau, floor=0.0) -> np.ndarray:
    """area x the exGaussian density at t (same units as mu, sigma, tau), plus `floor`."""
    t = np.asarray(t, dtype=np.float64)
    z = ((mu - t) / sigma + sigma / tau) / math.sqrt(2.0)
    small = z < 0  # there exp(sigma^2/2tau^2 - (t-mu)/tau) erfc(z) cannot overflow
    out = np.empty_like(t)
    out[~small] = np.exp(-0.5 * ((t[~small] - mu) / sigma) ** 2) * _erfcx(z[~small])
    ts = t[small]
    out[small] = np.exp(0.5 * (sigma / tau) ** 2 - (ts - mu) / tau) * _ERFC(z[small])
    return area * out / (2.0 * tau) + floor


@dataclass(frozen=True)
class ExGaussFit:
    """In bins of the profile fitted: mu (the Gaussian's centre), sigma, tau; the mode."""

    area: float
    mu: float
    sigma: float
    tau: float
    floor: float
    mode: float
    converged: bool


def _model(theta, t):
    log_area, mu, log_sigma, log_tau, floor = theta
    return exgauss(t, math.exp(log_area), mu, math.exp(log_sigma), math.exp(log_tau), floor)


def fit_exgauss(t, y, weights, start, *, iterations: int = 80) -> ExGaussFit | None:
    """Least squares of `y` (weights: 1 / sd per point) by exgauss; `start` = (area, mu,
    sigma, tau, floor). None where the fit leaves the data (a width below 1/100 bin or above
    the window)."""
    t, y, w = (np.asarray(a, dtype=np.float64) for a in (t, y, weights))
    a0, mu0, s0, tau0, f0 = start
    theta = np.array([math.log(a0), mu0, math.log(s0), math.log(tau0), f0])
    res = lambda th: (_model(th, t) - y) * w  # noqa: E731
    r, damping, converged = res(theta), 1e-3, False
    for _ in range(iterations):
        jac = _jacobian(res, theta, r)
        grad, normal = jac.T @ r, jac.T @ jac
        step = np.linalg.solve(normal + damping * np.diag(np.diag(normal) + 1e-12), -grad)
        trial = theta + step
        r_trial = res(trial) if np.all(np.isfinite(trial)) and abs(trial[2]) < 30 \
            and abs(trial[3]) < 30 else np.full_like(r, np.inf)
        if np.all(np.isfinite(r_trial)) and r_trial @ r_trial < r @ r:
            gain = (r @ r - r_trial @ r_trial) / max(r @ r, TINY)
            theta, r, damping = trial, r_trial, max(damping / 3, 1e-9)
            if gain < 1e-10 and np.max(np.abs(step)) < 1e-6:
                converged = True
                break
        else:
            damping *= 4
            if damping > 1e12:
                converged = True  # no step improves: a minimum (or a flat valley)
                break
    area, mu, sigma, tau = math.exp(theta[0]), theta[1], math.exp(theta[2]), math.exp(theta[3])
    span = float(t.max() - t.min())
    if not (0.01 < sigma < span and 0.01 < tau < span):
        return None
    return ExGaussFit(area, mu, sigma, tau, float(theta[4]), _mode(mu, sigma, tau), converged)


def _jacobian(res, theta, r):
    jac = np.empty((r.size, theta.size))
    for i in range(theta.size):
        h = 1e-6 * max(1.0, abs(theta[i]))
        bumped = theta.copy()
        bumped[i] += h
        jac[:, i] = (res(bumped) - r) / h
    return jac


def _mode(mu: float, sigma: float, tau: float) -> float:
    """The exGaussian's peak (bins), found on a fine grid around mu .. mu + tau."""
    t = np.linspace(mu - 3 * sigma, mu + 3 * sigma + tau, 2001)
    return float(t[np.argmax(exgauss(t, 1.0, mu, sigma, tau))])


def tail_tau(profile: np.ndarray, peak: int) -> float | None:
    """The tail's time constant (bins) from a straight line through log(profile) between the
    peak and where it has fallen to e^-3 of it: for a response whose rise is cut off."""
    top = profile[peak]
    after = profile[peak:]
    stop = np.flatnonzero(after < top * math.exp(-3.0))
    n = int(stop[0]) if stop.size else after.size
    seg = after[:n]
    keep = seg > 0
    if keep.sum() < 3:
        return None
    slope = np.polyfit(np.flatnonzero(keep), np.log(seg[keep]), 1)[0]
    return float(-1.0 / slope) if slope < 0 else None
