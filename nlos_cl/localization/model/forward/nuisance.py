"""The Gaussian likelihood's nuisances: per detector a slow background under the signal (a
constant and a ramp over the row's window of samples), estimated with the targets'
amplitudes in the same linear solve and profiled out (the fit's parameters do not change).

data.row_floors takes off a level measured outside the window; it cannot see a background
that varies under the signal (light that bounced once more, interreflection) nor a floor in a
record too short to have bins outside. Here each row's model is
    mu_d(t) = sum_k a_k m_kd(t) + c_0d + c_1d t',   t' in [-1, 1] across the row's samples,
so c_0d is the background at the window's middle and 2 c_1d its rise from first sample to last.
The noise is one sd per detector, so the weighted least squares of the c's is each row's own
ordinary least squares: the amplitudes are solved on the rows with the basis projected out,
then the c's from what the targets leave (exact: the c's are free, the a's >= 0).

Kept only where the row supports them (`supported`): a row's terms are on where the mean of the
samples in the first EDGE_M of path of its window (before the signal, in the margin
data.gaussian_observation leaves) stands EDGE_SIGNIFICANCE standard errors clear of 0: light
that arrives before any path to the target cannot be the target's. (The window's far end holds
the targets' own tails: tested there too, 2 of 9 and 5 of 7 rows of one-target boxes got terms,
draw 19 3.5 -> 4.2 cm.) Always on, the ramp took part of the closed shapes' depth tails:
one-target draws 1, 3, 8 went 3.1 / 1.5 / 5.0 -> 7.8 / 5.4 / 9.0 mm. The test reads the data
alone, once, so the cost stays a function of the targets' parameters."""
from __future__ import annotations

import numpy as np

# Legendre terms per row: 0 a constant only, 1 a constant and a ramp, 2 also a parabola.
ORDER = 1
EDGE_M = 0.25  # of path at the start of a row's window, where the support is tested
EDGE_SIGNIFICANCE = 5.0  # standard errors (as data.row_floors' level)


def supported(obs) -> np.ndarray:
    """(D,) bool: rows whose window's leading edge (the first EDGE_M of path of the valid
    samples) holds a level EDGE_SIGNIFICANCE standard errors clear of 0 (the filtered noise's
    correlation obs.rho counted in the error). Rows with fewer than 4 edges of valid samples,
    or edges of fewer than 2 samples, get none."""
    valid = np.asarray(obs.valid, bool)
    q = (EDGE_M / np.asarray(obs.dpath, float)).astype(int)
    rank = np.cumsum(valid, axis=1)  # 1 at a row's first valid sample, 2 at its second, ...
    edge = valid & (rank <= q[:, None])
    level = np.sum(np.where(edge, obs.y, 0.0), axis=1) / np.maximum(q, 1)
    sizes, which = np.unique(q, return_inverse=True)  # rows share a few edge sizes
    se = np.asarray(obs.noise, float) * np.array([_mean_sd(int(k), obs.rho)
                                                  for k in sizes])[which.reshape(-1)]
    return (q >= 2) & (rank[:, -1] >= 4 * q) & (np.abs(level) > EDGE_SIGNIFICANCE * se)


def _mean_sd(q: int, rho) -> float:
    """The sd of the mean of q consecutive samples of unit sd and correlation rho at lag j."""
    if q < 1:
        return np.inf
    lags = np.abs(np.arange(q)[:, None] - np.arange(q)[None, :])
    return float(np.sqrt(rho[np.minimum(lags, len(rho) - 1)].sum())) / q


class Background:
    """The basis (p, D, n) of each row's background terms over its valid samples (zero
    elsewhere) and the pseudo-inverse of each row's (p, p) Gram matrix."""

    def __init__(self, valid, order: int = ORDER, rows=None):
        """rows: (D,) bool, the rows given terms (`supported`); None: all."""
        valid = np.asarray(valid, bool)
        n = valid.shape[1]
        seen = valid.any(axis=1)
        first = np.where(seen, valid.argmax(axis=1), 0)
        last = np.where(seen, n - 1 - valid[:, ::-1].argmax(axis=1), 0)
        mid, half = 0.5 * (first + last), np.maximum(0.5 * (last - first), 1.0)
        t = (np.arange(n)[None, :] - mid[:, None]) / half[:, None]
        terms = [np.ones_like(t), t, 1.5 * t * t - 0.5][:order + 1]
        on = valid if rows is None else valid & np.asarray(rows, bool)[:, None]
        self.basis = np.stack([np.where(on, b, 0.0) for b in terms])
        self.rows = on.any(axis=1)
        gram = np.einsum("bdn,cdn->dbc", self.basis, self.basis)
        self.gram_pinv = np.linalg.pinv(gram)  # a row with < p valid samples: pinv, not inv
        self.p, self.d = len(terms), valid.shape[0]

    def coefficients(self, x) -> np.ndarray:
        """(..., p, D): each row of x (..., D, n) fitted by the basis (least squares)."""
        rhs = np.einsum("bdn,...dn->...db", self.basis, x)
        return np.einsum("dbc,...dc->...bd", self.gram_pinv, rhs)

    def fitted(self, coef) -> np.ndarray:
        """(..., D, n): the background of coefficients coef (..., p, D)."""
        return np.einsum("...bd,bdn->...dn", coef, self.basis)

    def project(self, x) -> np.ndarray:
        """x (..., D, n) less its least-squares fit by each row's basis."""
        return x - self.fitted(self.coefficients(x))

    def trace_with(self, d: int, rows, block) -> float:
        """trace(P C) over detector d's valid samples `rows` (a bool mask): P the projection on
        its basis, C the noise correlation `block` there (the degrees of freedom the
        background takes from E[RSS])."""
        b = self.basis[:, d, rows]
        return float(np.trace(self.gram_pinv[d] @ (b @ block @ b.T)))


def summary(coef, sd=None, peak=None) -> dict:
    """The fitted backgrounds per detector summarized for the fit's diagnostics: the level at
    the window's middle and the rise across it (data units; `peak`: the rows' largest value,
    for shares), each detector's largest |level| / sd where `sd` (p, D) is given."""
    coef = np.asarray(coef, float)
    level = coef[0]
    out = {"background_rows": int(np.count_nonzero(np.any(coef != 0, axis=0))),
           "background_level_median": float(np.median(level)),
           "background_level_max_abs": float(np.max(np.abs(level)))}
    if len(coef) > 1:
        out["background_rise_max_abs"] = float(np.max(np.abs(2.0 * coef[1])))
    if peak is not None and peak > 0:
        out["background_level_share_max"] = float(np.max(np.abs(level)) / peak)
    if sd is not None:
        z = np.abs(coef) / np.maximum(np.asarray(sd, float), 1e-300)
        out["background_z_max"] = float(np.max(z))
    return out
