"""The Gauss-fit baseline (paper Eq. 25): one Gaussian least-squares fitted to each whole
histogram, without a manually chosen interval, as the filter is compared against."""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.optimize import OptimizeWarning, curve_fit


def _gauss(t, amplitude, centre, width):
    return amplitude * np.exp(-0.5 * ((t - centre) / width) ** 2)


def _gauss_jac(t, amplitude, centre, width):
    z = (t - centre) / width
    e = np.exp(-0.5 * z * z)
    return np.stack([e, amplitude * e * z / width, amplitude * e * z * z / width], axis=1)


@dataclass(frozen=True)
class GaussFit:
    amplitude: np.ndarray  # per row, same unit as the data
    centre_s: np.ndarray
    width_s: np.ndarray  # sigma
    converged: np.ndarray  # bool per row

    def curves(self, t_s: np.ndarray) -> np.ndarray:
        return _gauss(t_s[None, :], self.amplitude[:, None], self.centre_s[:, None],
                      self.width_s[:, None])


def fit_gaussians(data: np.ndarray, t_s: np.ndarray) -> GaussFit:
    """Least-squares fit of A exp(-(t - mu)^2 / (2 s^2)) to every row over the whole record.

    Start: A and mu from the row's maximum, s from the number of bins above half of it.
    The fit is converged when SciPy's trust-region solver stops on its tolerances (not on the
    evaluation limit) with finite, positive width.
    """
    dt = float(t_s[1] - t_s[0])
    n = len(data)
    amp, centre, width = np.zeros(n), np.zeros(n), np.zeros(n)
    ok = np.zeros(n, dtype=bool)
    span = float(t_s[-1] - t_s[0])
    for row in range(n):  # a handful of rows; each fit is vectorized over bins
        y = np.asarray(data[row], dtype=np.float64)
        peak = int(np.argmax(y))
        a0 = max(float(y[peak]), np.finfo(float).tiny)
        above = int(np.count_nonzero(y > 0.5 * a0))
        s0 = max(above * dt / 2.355, dt)
        scale = a0  # fit in units of the peak so the solver's tolerances mean something
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error", OptimizeWarning)
                p, _ = curve_fit(_gauss, t_s, y / scale, p0=(1.0, float(t_s[peak]), s0),
                                 jac=_gauss_jac, method="trf", x_scale=(1.0, s0, s0),
                                 bounds=([0.0, t_s[0] - span, dt / 10], [np.inf, t_s[-1] + span,
                                                                         10 * span]),
                                 max_nfev=2000)
            amp[row], centre[row], width[row] = p[0] * scale, p[1], p[2]
            ok[row] = bool(np.all(np.isfinite(p)) and p[2] > 0)
        except (RuntimeError, OptimizeWarning):
            amp[row], centre[row], width[row] = a0, float(t_s[peak]), s0
    return GaussFit(amp, centre, width, ok)
