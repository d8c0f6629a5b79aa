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
then the c's from what the targets leave (exact: the c's are free, the a's >= 0)."""
from __future__ import annotations

import numpy as np

# Legendre terms per row: 0 a constant only, 1 a constant and a ramp, 2 also a parabola.
ORDER = 1


class Background:
    """The basis (p, D, n) of each row's background terms over its valid samples (zero
    elsewhere) and the pseudo-inverse of each row's (p, p) Gram matrix."""

    def __init__(self, valid, order: int = ORDER):
        valid = np.asarray(valid, bool)
        n = valid.shape[1]
        seen = valid.any(axis=1)
        first = np.where(seen, valid.argmax(axis=1), 0)
        last = np.where(seen, n - 1 - valid[:, ::-1].argmax(axis=1), 0)
        mid, half = 0.5 * (first + last), np.maximum(0.5 * (last - first), 1.0)
        t = (np.arange(n)[None, :] - mid[:, None]) / half[:, None]
        terms = [np.ones_like(t), t, 1.5 * t * t - 0.5][:order + 1]
        self.basis = np.stack([np.where(valid, b, 0.0) for b in terms])
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
    out = {"background_level_median": float(np.median(level)),
           "background_level_max_abs": float(np.max(np.abs(level)))}
    if len(coef) > 1:
        out["background_rise_max_abs"] = float(np.max(np.abs(2.0 * coef[1])))
    if peak is not None and peak > 0:
        out["background_level_share_max"] = float(np.max(np.abs(level)) / peak)
    if sd is not None:
        z = np.abs(coef) / np.maximum(np.asarray(sd, float), 1e-300)
        out["background_z_max"] = float(np.max(z))
    return out
