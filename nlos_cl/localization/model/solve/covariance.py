"""The covariance of a model fit (model.fit's FitResult) and its diagnostics.

AWGN: the sandwich (J'J)^-1 J' C J (J'J)^-1 of weighted least squares on filtered samples
whose noise correlation C comes from the filter's taps (no free factor), times the Birge ratio
max(1, RSS / E[RSS]) where E[RSS] = tr((I - H) C): when the model does not explain the data
to within the noise, the covariance grows by the measured excess. Photon counts: the inverse
Fisher information of the Poisson likelihood. Both include the linear factors (AWGN: the
amplitudes, and each detector's background terms, profiled out by projecting the derivatives
off their basis: the target block of the sandwich is unchanged by it). The derivatives are
analytic where model.fit.analytic_derivatives has them, else central differences.
"""
from __future__ import annotations

import numpy as np

from ....core.constants import TINY
from ..forward import late, nuisance
from ..shapes import plate
from .fit import (
    FitResult,
    _prior_terms,
    analytic_derivatives,
    shadowed_by,
    shape_of,
    stepped_columns,
)
from .records import Covariance


def _mean_jacobian(problem, params, lin, free):
    """d mu / d (free target parameters, linear factors): (D, n, P). Analytic where
    `analytic_derivatives` has them (host plates that cannot shadow each other), else central
    differences."""
    steps = shape_of(problem).STEPS
    which = [(k, i) for k in range(len(params)) for i in np.flatnonzero(free)]
    slopes = analytic_derivatives(problem, params)
    # each target's change through its amplitude and its late copies' (forward.late)
    scaled = getattr(problem, "scaled", lambda k, n, x, a: a[k] * x)
    if slopes is not None:
        cols = problem.columns(params)
        blocks = [scaled(k, len(params), slopes[k, i], lin) for k, i in which]
    elif shadowed_by(problem, params) is not None:
        blocks, cols = _shadowed_blocks(problem, params, lin, which, steps)
    else:
        rows = [p.copy() for p in params]  # the targets, then hi, lo, parameter after parameter
        like = list(params)  # the row each one steps from
        for k, i in which:
            for sign in (1.0, -1.0):
                rows.append(params[k].copy())
                rows[-1][i] += sign * steps[i]
                like.append(params[k])
        evaluated = problem.column_batch(np.array(rows), np.array(like))
        cols, moved = evaluated[:len(params)], evaluated[len(params):]
        blocks = [scaled(k, len(params), (moved[2 * n] - moved[2 * n + 1]) / (2 * steps[i]),
                         lin) for n, (k, i) in enumerate(which)]
    blocks.extend(cols)  # counts' per-detector backgrounds: `_poisson_information`
    blocks.extend(_late_columns(problem, cols, lin))
    return cols, np.stack(blocks, axis=-1)


def _late_columns(problem, cols, lin) -> list:
    """The late copies (forward.late) a fit uses (`late.in_use`): nuisance columns."""
    copies = getattr(problem, "copies", lambda c: None)(cols)
    if copies is None:
        return []
    amp, _, b = problem.split(lin, len(cols))
    return [copies[k, j] for k, j in zip(*np.nonzero(late.in_use(amp, b)))]


def _shadowed_blocks(problem, params, lin, which, steps):
    """`_mean_jacobian`'s derivative blocks where targets shadow each other: moving target k
    changes the columns of the targets it shadows too, so d mu = sum_j a_j d(column j)."""
    cols = problem.columns(params)
    moves = []
    for k, i in which:
        for sign in (1.0, -1.0):
            row = params[k].copy()
            row[i] += sign * steps[i]
            moves.append((k, row))
    moved = stepped_columns(problem, params, cols, moves)
    amp = np.asarray(lin[:len(params)])
    return [np.tensordot(amp, moved[2 * n] - moved[2 * n + 1], 1) / (2 * steps[i])
            for n, (k, i) in enumerate(which)], list(cols)


def _reused_jacobian(problem, result, free):
    """(cols, j): the columns at the solution and the whitened derivatives of the mean over
    the valid samples (rows) and (free target parameters, amplitudes) (columns), the target
    parameters' taken from the solver's last Jacobian; None where that does not hold: not
    AWGN, no Jacobian, an amplitude at its bound of 0 (the profile's derivative is another
    there), or a solution more than REUSE_MOVE from the Jacobian's point.

    Why it may: the solver's Jacobian is that of the profiled residuals, d r / d theta =
    -(I - P_A) d mu / d theta (whitened; P_A the projection on the amplitudes' columns), and
    [-(I - P_A) J_theta, A] spans what [J_theta, A] does by a change of variables that leaves
    the target parameters' block of the sandwich and trace(H C) unchanged, so the covariance
    of the target parameters and the Birge ratio are the same. What differs: the solver's
    forward differences (2 mm, 4 mrad, at frozen cell statistics: a truncation of ~h / (2
    sigma), sds 0.2-5 % from the analytic ones, tests/localization/model/test_model_covariance_reuse.py) taken up
    to one accepted step before the solution (a warm fit stops once a step promises less than
    WARM_ATOL of cost: ~0.3 sd)."""
    if problem.obs.mode != "gauss" or result.jacobian is None:
        return None
    at, jac = result.jacobian
    k = len(result.params)
    if np.any(np.asarray(result.linear[:k]) <= 0):
        return None
    mask = np.tile(np.asarray(free, bool), k)
    data = jac[:result.n_residuals]
    move = (np.asarray(result.params) - np.asarray(at)).reshape(-1)[mask]
    if float(np.linalg.norm(data @ move)) > REUSE_MOVE:
        return None
    obs = problem.obs
    cols = problem.columns(result.params) if result.columns is None else result.columns
    amplitudes = [(c / obs.noise[:, None])[obs.valid]
                  for c in list(cols) + _late_columns(problem, cols, result.linear)]
    return cols, np.column_stack([-data, *amplitudes])


def _correlated_terms(obs, j, bg=None):
    """J^T C J, C J (rows of j) and trace((I - P_B) C) for the correlation C of the weighted
    residuals, which is block diagonal (one Toeplitz block per detector: the filter correlates
    a detector's samples, not two detectors'), summed block by block: a 1,024-detector patch
    never builds the dense (samples x samples) matrix (93,184^2 floats, 65 GiB). bg: the
    backgrounds' basis (nuisance.Background), whose projection P_B takes its trace off."""
    idx = np.arange(obs.n)
    toeplitz = obs.rho[np.abs(idx[:, None] - idx[None, :])]
    meat, trace, at = np.zeros((j.shape[1], j.shape[1])), 0.0, 0
    cj = np.empty_like(j)
    for d, v in enumerate(obs.valid):  # j's rows: the valid samples, detector after detector
        block = toeplitz[np.ix_(v, v)]
        rows = j[at:at + len(block)]
        cj[at:at + len(block)] = block @ rows
        meat += rows.T @ cj[at:at + len(block)]
        trace += float(np.trace(block)) - (0.0 if bg is None else bg.trace_with(d, v, block))
        at += len(block)
    return meat, trace, cj


def _off_background(obs, bg, j):
    """j (valid rows, P) with each detector's background basis projected out of its rows."""
    full = np.zeros(obs.valid.shape + (j.shape[1],))
    full[obs.valid] = j
    return np.moveaxis(bg.project(np.moveaxis(full, -1, 0)), 0, -1)[obs.valid]


def _background_sd(obs, bg, j_raw, inv, meat, cj) -> np.ndarray:
    """(p, D) sds of the background coefficients (data units, before the Birge ratio): per
    detector c = E (y - J theta) with E its rows' least-squares operator and theta = inv
    J~' y (J~ the projected j), so c = M y with M = E S_d - E J_d inv J~', whose C-variance
    M C M' is summed from the blocks (`cj`: C J~)."""
    out, at = np.zeros((bg.p, bg.d)), 0
    for d, v in enumerate(obs.valid):
        m = int(v.sum())
        e = bg.gram_pinv[d] @ bg.basis[:, d, v]  # (p, m)
        idx = np.arange(obs.n)
        block = obs.rho[np.abs(idx[v][:, None] - idx[v][None, :])]
        lm = e @ j_raw[at:at + m] @ inv  # (p, P)
        ec = e @ cj[at:at + m]  # E C_dd J~_d
        var = e @ block @ e.T - ec @ lm.T - lm @ ec.T + lm @ meat @ lm.T
        out[:, d] = np.sqrt(np.maximum(np.diag(var), 0.0)) * obs.noise[d]
        at += m
    return out


def _poisson_information(obs, mu, jmu) -> np.ndarray:
    """The Fisher information of Poisson counts for the target parameters and amplitudes
    (jmu's P columns), the per-detector backgrounds profiled out: with B the backgrounds'
    block (diagonal: detector d's background moves only its own bins, information
    sum_d 1 / lambda) and C the cross terms, the Schur complement A - C B^-1 C^T, whose inverse
    is the target block of the full inverse. The full matrix, one column per detector, was
    (D, n, D) dense: 271 GiB for a 4,096-point confocal scan of 2,165 bins."""
    w = np.where(obs.valid, 1.0 / np.maximum(mu, 1e-12), 0.0)  # (D, n)
    weighted = jmu * w[:, :, None]
    a = np.einsum("dnp,dnq->pq", weighted, jmu)
    cross = weighted.sum(axis=1)  # (D, P): sum over a detector's bins of J / lambda
    b = w.sum(axis=1)  # (D,)
    seen = b > 0  # a detector without valid bins has no background to profile
    return a - cross[seen].T @ (cross[seen] / b[seen, None])


def _scaled_pinv(a) -> np.ndarray:
    """Pseudo-inverse of a normal matrix whose columns differ by many orders of magnitude
    (metres, radians, amplitudes in any unit): equilibrated first, so that pinv's relative
    cut-off drops only real degeneracies, not small units."""
    s = np.sqrt(np.maximum(np.diag(a), TINY))
    return np.linalg.pinv(a / np.outer(s, s)) / np.outer(s, s)


# How far (in the whitened residuals' norm: ~ the fit's sds) the solution may lie from the
# point of the solver's last Jacobian for `reuse` to take that Jacobian (see `covariance`).
REUSE_MOVE = 0.5


def _gauss_sandwich(problem, result, jmu, reused: bool, precision, mu):
    """(covariance, info, background sds or None) of an AWGN fit: the sandwich over the
    derivatives jmu (whitened rows already where `reused`) with the backgrounds profiled out,
    times the Birge ratio; info the Birge ratio and the backgrounds' summary."""
    obs = problem.obs
    j = jmu if reused else (jmu / obs.noise[:, None, None])[obs.valid]
    bg = getattr(problem, "background", lambda: None)()  # a test's stub may have none
    j_raw, j = j, (j if bg is None else _off_background(obs, bg, j))
    meat, trace, cj = _correlated_terms(obs, j, bg)
    inv = _scaled_pinv(j.T @ j + np.diag(precision))
    cov = inv @ (meat + np.diag(precision)) @ inv
    r = ((obs.y - mu) / obs.noise[:, None])[obs.valid]
    expected = float(trace - np.trace(inv @ meat))
    birge = float(r @ r) / max(expected, 1.0)
    info, sd = {"birge_ratio": birge}, None
    k = len(result.params)
    if bg is not None and len(result.linear) > k:
        # a reused Jacobian's columns are the profiled ones, not d mu: no sds from them
        sd = None if reused else \
            _background_sd(obs, bg, j_raw, inv, meat, cj) * np.sqrt(max(1.0, birge))
        coef = np.reshape(result.linear[k:k + bg.p * bg.d], (bg.p, -1))
        info.update(nuisance.summary(coef, sd, float(np.max(np.abs(obs.y)))))
    return cov * max(1.0, birge), info, sd


def background_estimates(problem, result: FitResult, free):
    """(coefficients, sds), each (p, D) in data units, of an AWGN fit's background terms
    (model.forward.nuisance: the level at the window's middle, then the ramp's half rise),
    the sds with the Birge ratio; None where the fit has none."""
    if problem.obs.mode != "gauss" or problem.background() is None:
        return None
    cols, jmu = _mean_jacobian(problem, result.params, result.linear, free)
    precision = np.zeros(jmu.shape[-1])  # the noise's part alone (no prior)
    _, _, sd = _gauss_sandwich(problem, result, jmu, False, precision,
                               problem.mean(cols, result.linear))
    k = len(result.params)
    return np.reshape(result.linear[k:k + sd.size], sd.shape), sd


def covariance(problem, result: FitResult, free, reuse: bool = False
               ) -> Covariance:
    """Covariance of every target parameter (K*N_PARAMS square; inf on fixed ones) and
    diagnostics. reuse: take the target parameters' derivatives from the solver's last
    Jacobian (result.jacobian; no model call) where `_reused_jacobian` allows, else compute
    them (`_mean_jacobian`)."""
    obs, params = problem.obs, result.params
    reused = _reused_jacobian(problem, result, free) if reuse else None
    # jmu: d mu / d (parameters, amplitudes), (D, n, P); a reused one comes whitened, (rows, P)
    cols, jmu = reused if reused is not None else \
        _mean_jacobian(problem, params, result.linear, free)
    mu = problem.mean(cols, result.linear)
    n_free = int(np.count_nonzero(free)) * len(params)
    # a MAP fit's prior adds its precision to the information (model.fit's `prior`)
    precision = np.zeros(jmu.shape[-1])
    at, _, sd = _prior_terms(result.prior, params.shape, np.tile(np.asarray(free, bool),
                                                                 len(params)))
    precision[at] = 1.0 / sd ** 2  # the free target parameters come first, as in _prior_terms
    if obs.mode == "gauss":
        cov, info, _ = _gauss_sandwich(problem, result, jmu, reused is not None, precision, mu)
    else:
        cov = _scaled_pinv(_poisson_information(obs, mu, jmu) + np.diag(precision))
        info = {"deviance": result.cost, "n_bins": int(obs.valid.sum())}
    full = np.full((params.size, params.size), np.inf)
    mask = np.tile(np.asarray(free, bool), len(params))
    full[np.ix_(mask, mask)] = cov[:n_free, :n_free]
    n = shape_of(problem).N_PARAMS
    for k in np.flatnonzero(np.asarray(result.linear[:len(params)]) <= 0):
        # amplitude 0 (held at the bound: the data want none of this target): its parameters'
        # derivatives are 0, so pinv gave them a variance of 0, not the infinity they have
        full[k * n:(k + 1) * n, :] = np.inf
        full[:, k * n:(k + 1) * n] = np.inf
    return Covariance(full, info)


def centre_covariance(cov_all, k, shape=plate) -> np.ndarray:
    """The (x, y, z) block of target k (rows of shape.N_PARAMS parameters, x, y, z first); an
    unobservable (fixed) axis has infinite variance and no correlation with the others."""
    s = slice(k * shape.N_PARAMS, k * shape.N_PARAMS + 3)
    c = np.array(cov_all[s, s], dtype=np.float64)
    fixed = ~np.isfinite(np.diag(c))
    c[fixed, :] = 0.0
    c[:, fixed] = 0.0
    c[fixed, fixed] = np.inf
    return c
