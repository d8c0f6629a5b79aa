"""The nonlinear fit (SciPy least squares, trust region with bounds) of K plates, the linear
factors profiled out at every step (variable projection), and the covariance of the result.

Finite-difference steps are absolute (2 mm, 4 mrad): the forward kernel works in float32, so
SciPy's default relative steps (~1e-8) would differentiate rounding noise. A Jacobian column
re-simulates only the plate whose parameter moved.

Covariance. AWGN: the sandwich (J'J)^-1 J' C J (J'J)^-1 of weighted least squares on filtered
samples whose noise correlation C comes from the filter's taps (no free factor), times the
Birge ratio max(1, RSS / E[RSS]) where E[RSS] = tr((I - H) C): when the model does not explain
the data to within the noise, the covariance grows by the measured excess. Photon counts: the
inverse Fisher information of the Poisson likelihood. Both include the linear factors.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import plate

STEPS = np.array([2e-3, 2e-3, 2e-3, 2e-3, 2e-3, 4e-3])
X_SCALE = np.array([0.05, 0.05, 0.05, 0.1, 0.1, 0.1])


@dataclass
class FitResult:
    params: np.ndarray  # (K, 6)
    linear: np.ndarray  # amplitudes (and backgrounds for Poisson)
    cost: float  # sum of squared residuals (= -2 log L + const)
    n_residuals: int
    nfev: int
    cov: np.ndarray | None = None  # (K*6, K*6) over all parameters (inf where fixed)


class _Objective:
    """Residual and Jacobian of the profiled problem over the free parameters."""

    def __init__(self, problem, params0, free):
        self.problem = problem
        self.base = np.array(params0, dtype=np.float64).reshape(-1, plate.N_PARAMS)
        self.free = np.tile(np.asarray(free, bool), len(self.base))
        self._key, self._cols, self._lin = None, None, None

    def full(self, theta):
        p = self.base.reshape(-1).copy()
        p[self.free] = theta
        return p.reshape(self.base.shape)

    def _eval(self, theta):
        key = np.asarray(theta).tobytes()
        if key != self._key:
            cols = self.problem.columns(self.full(theta))
            self._lin = self.problem.linear(cols, self._warm(cols))
            self._key, self._cols = key, cols
        return self._cols, self._lin

    def _warm(self, cols):
        lin = self._lin
        return lin if lin is not None and len(lin) == len(cols) + self.problem.obs.y.shape[0] \
            else None

    def residual(self, theta):
        cols, lin = self._eval(theta)
        return self.problem.residual(cols, lin)

    def jac(self, theta):
        cols, lin = self._eval(theta)
        r0 = self.problem.residual(cols, lin)
        full = self.full(theta)
        free_idx = np.flatnonzero(self.free)
        out = np.empty((r0.size, free_idx.size))
        for j, flat in enumerate(free_idx):
            k, i = divmod(flat, plate.N_PARAMS)
            p = full[k].copy()
            p[i] += STEPS[i]
            moved = cols.copy()
            moved[k] = self.problem.column(p)
            r = self.problem.residual(moved, self.problem.linear(moved, lin))
            out[:, j] = (r - r0) / STEPS[i]
        return out


def fit(problem, params0, free, max_nfev=30) -> FitResult:
    """Least squares from params0 (K, 6) over the parameters marked in `free` (6,)."""
    from scipy.optimize import least_squares
    obj = _Objective(problem, params0, free)
    lo = np.tile(plate.LOWER, len(obj.base))[obj.free]
    hi = np.tile(plate.UPPER, len(obj.base))[obj.free]
    theta0 = np.clip(obj.base.reshape(-1)[obj.free], lo + 1e-6, hi - 1e-6)
    sol = least_squares(obj.residual, theta0, jac=obj.jac, bounds=(lo, hi), method="trf",
                        x_scale=np.tile(X_SCALE, len(obj.base))[obj.free], max_nfev=max_nfev,
                        ftol=1e-7, xtol=1e-5)
    cols, lin = obj._eval(sol.x)
    r = problem.residual(cols, lin)
    return FitResult(obj.full(sol.x), lin, float(r @ r), int(r.size), int(sol.nfev))


def _mean_jacobian(problem, params, lin, free):
    """d mu / d (free plate parameters, linear factors), central differences: (D, n, P)."""
    cols = problem.columns(params)
    k_targets = len(params)
    blocks = []
    for k in range(k_targets):
        for i in np.flatnonzero(free):
            hi, lo = params[k].copy(), params[k].copy()
            hi[i] += STEPS[i]
            lo[i] -= STEPS[i]
            blocks.append(lin[k] * (problem.column(hi) - problem.column(lo)) / (2 * STEPS[i]))
    blocks.extend(cols)
    if problem.obs.mode == "poisson":
        n_det = problem.obs.y.shape[0]
        blocks.extend(np.eye(n_det)[:, :, None] * problem.obs.valid[None])
    return cols, np.stack(blocks, axis=-1)


def _correlated_terms(obs, j):
    """J^T C J and trace(C) for the correlation C of the weighted residuals, which is block
    diagonal (one Toeplitz block per detector: the filter correlates a detector's samples, not
    two detectors'), summed block by block: a 1,024-detector patch never builds the dense
    (samples x samples) matrix (93,184^2 floats, 65 GiB)."""
    idx = np.arange(obs.n)
    toeplitz = obs.rho[np.abs(idx[:, None] - idx[None, :])]
    meat, trace, at = np.zeros((j.shape[1], j.shape[1])), 0.0, 0
    for v in obs.valid:  # j's rows are the valid samples, detector after detector
        block = toeplitz[np.ix_(v, v)]
        rows = j[at:at + len(block)]
        meat += rows.T @ block @ rows
        trace += float(np.trace(block))
        at += len(block)
    return meat, trace


def _scaled_pinv(a) -> np.ndarray:
    """Pseudo-inverse of a normal matrix whose columns differ by many orders of magnitude
    (metres, radians, amplitudes in any unit): equilibrated first, so that pinv's relative
    cut-off drops only real degeneracies, not small units."""
    s = np.sqrt(np.maximum(np.diag(a), 1e-300))
    return np.linalg.pinv(a / np.outer(s, s)) / np.outer(s, s)


def covariance(problem, result: FitResult, free) -> tuple[np.ndarray, dict]:
    """Covariance of every plate parameter (K*6 square; inf on fixed ones) and diagnostics."""
    obs, params = problem.obs, result.params
    cols, jmu = _mean_jacobian(problem, params, result.linear, free)
    mu = problem.mean(cols, result.linear)
    n_free = int(np.count_nonzero(free)) * len(params)
    if obs.mode == "gauss":
        j = (jmu / obs.noise[:, None, None])[obs.valid]
        meat, trace = _correlated_terms(obs, j)
        inv = _scaled_pinv(j.T @ j)
        cov = inv @ meat @ inv
        r = ((obs.y - mu) / obs.noise[:, None])[obs.valid]
        expected = float(trace - np.trace(inv @ meat))
        birge = float(r @ r) / max(expected, 1.0)
        cov = cov * max(1.0, birge)
        info = {"birge_ratio": birge}
    else:
        lam = np.maximum(mu, 1e-12)[obs.valid]
        j = jmu[obs.valid]
        cov = _scaled_pinv(j.T @ (j / lam[:, None]))
        info = {"deviance": result.cost, "n_bins": int(obs.valid.sum())}
    full = np.full((params.size, params.size), np.inf)
    mask = np.tile(np.asarray(free, bool), len(params))
    full[np.ix_(mask, mask)] = cov[:n_free, :n_free]
    return full, info


def centre_covariance(cov_all, k) -> np.ndarray:
    """The (x, y, z) block of target k; an unobservable (fixed) axis has infinite variance and
    no correlation with the others."""
    s = slice(k * plate.N_PARAMS, k * plate.N_PARAMS + 3)
    c = np.array(cov_all[s, s], dtype=np.float64)
    fixed = ~np.isfinite(np.diag(c))
    c[fixed, :] = 0.0
    c[:, fixed] = 0.0
    c[fixed, fixed] = np.inf
    return c
