"""The photon counts' amplitudes of a forward-difference Jacobian's stepped columns, solved
together: each column set of a Jacobian is the fit's point with one parameter
moved, and its amplitudes and backgrounds are likelihood.Problem.linear's Newton solve from
the point's own (3-4 steps each). Alone, each solve is ~25 small NumPy calls a step on a few
thousand bins, so its cost is the calls' overhead; here the M solves of a Jacobian run as one
over a leading axis of M, every member stepping as it would alone and stopping where it would
alone (likelihood._poisson_newton's test, member by member): the same optima, summed in
another order (within 1e-12 of them)."""
from __future__ import annotations

import numpy as np

from ....core.constants import TINY
from ....core.stats import deviance_residuals
from ..forward.likelihood import BOUND_SHARE, NEWTON_ITERS


def stepped_linear(problem, stepped, lin) -> list:
    """[problem.linear(moved, lin) for moved in stepped]: stepped (M, K, D, n) the column sets,
    lin the point's linear factors (their warm start). Counts without late copies are solved
    together (`poisson_newton_many`); anything else (Gaussian data, late copies) one by one."""
    obs = problem.obs
    if obs.mode != "poisson" or getattr(obs, "late", None) is not None or len(stepped) < 2:
        return [problem.linear(moved, lin) for moved in stepped]
    stepped = np.asarray(stepped, np.float64)
    phi = np.repeat(np.asarray(lin, np.float64)[None], len(stepped), axis=0)
    try:
        return list(poisson_newton_many(obs.y, obs.valid.astype(np.float64), stepped, phi,
                                        NEWTON_ITERS))
    except np.linalg.LinAlgError:  # a singular member: each alone, as before
        return [problem.linear(moved, lin) for moved in stepped]


def stepped_residuals(problem, stepped, lin) -> list:
    """[problem.residual(moved, problem.linear(moved, lin)) for moved in stepped]: a
    Jacobian's profiled residuals; for counts without late copies the amplitudes together
    (`stepped_linear`) and the deviance residuals of all M at once (Problem.residual's)."""
    lins = stepped_linear(problem, stepped, lin)
    obs = problem.obs
    if obs.mode != "poisson" or getattr(obs, "late", None) is not None or len(stepped) < 2:
        return [problem.residual(moved, x) for moved, x in zip(stepped, lins)]
    phi, k, y = np.asarray(lins), np.shape(stepped)[1], obs.y
    lam = np.einsum("mk,mkdn->mdn", phi[:, :k], stepped) + phi[:, k:, None] * obs.valid
    np.maximum(lam, 1e-12, out=lam)
    return list(deviance_residuals(y, lam)[:, obs.valid])


def poisson_newton_many(y, valid, cols, phi, iters) -> np.ndarray:
    """likelihood._poisson_newton for M column sets cols (M, K, D, n) from phi (M, K + D),
    each member (a, then b per detector) kept >= 0 by the same bounded step, converged by the
    same test, and left at its last finite point where its step is not finite."""
    m, k = cols.shape[:2]
    flat = cols.reshape(m, k, -1)
    yv, vflat = y * valid, np.reshape(valid, -1)
    scale = np.concatenate([flat @ vflat, np.repeat(np.sum(valid, axis=1)[None], m, 0)], 1)
    total = float(np.sum(yv)) + 1.0
    phi = np.array(phi, np.float64)
    live = np.arange(m)
    for _ in range(iters):
        if not live.size:
            break
        f, p = flat[live], phi[live]
        n_live = len(live)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            lam = (p[:, None, :k] @ f).reshape((n_live,) + np.shape(y))
            lam += p[:, k:, None] * valid
            np.maximum(lam, 1e-12, out=lam)
            r = yv / lam
            w = yv / (lam * lam)
            r -= valid
            h_bb, g_b = np.sum(w, axis=2), np.sum(r, axis=2)  # (L, D)
            fine = np.all(np.isfinite(h_bb), axis=1) & np.all(np.isfinite(g_b), axis=1)
            fw = f * w.reshape(n_live, 1, -1)
            h_aa = fw @ f.transpose(0, 2, 1)  # (L, K, K)
            h_ab = fw.reshape((n_live, k) + np.shape(y)).sum(axis=3)  # (L, K, D)
            diag = np.arange(k)
            h_aa[:, diag, diag] += _ridge(h_aa[:, diag, diag])
            h_bb += _ridge(h_bb)
            g_a = (f @ r.reshape(n_live, -1, 1))[..., 0]
            h_bb = np.where(fine[:, None], h_bb, 1.0)  # a member that stops: any finite
            h_aa[~fine] = np.eye(k)  # numbers (its step is not taken)
            h_ab[~fine], g_a[~fine], g_b[~fine] = 0.0, 0.0, 0.0
            new = np.maximum(p + _arrow_solve(h_aa, h_ab, h_bb, g_a, g_b), BOUND_SHARE * p)
        fine &= np.all(np.isfinite(new), axis=1)
        moved = np.abs(new - p)
        done = np.all((moved <= 1e-9 * np.abs(p)) | (moved * scale[live] <= 1e-9 * total),
                      axis=1)
        phi[live[fine]] = new[fine]
        live = live[fine & ~done]
    return phi


def _ridge(diagonal) -> np.ndarray:
    """likelihood._ridge of each member's block diagonal (L, n): each member's own mean."""
    floor = 1e-3 * np.mean(diagonal, axis=1, keepdims=True)
    return 1e-9 * np.maximum(diagonal, floor) + TINY


def _arrow_solve(h_aa, h_ab, h_bb, g_a, g_b) -> np.ndarray:
    """likelihood._arrow_solve per member: (L, K + D) steps."""
    scaled = h_ab / h_bb[:, None, :]  # (L, K, D)
    schur = h_aa - scaled @ h_ab.transpose(0, 2, 1)
    rhs = g_a - (scaled @ g_b[..., None])[..., 0]
    step_a = np.linalg.solve(schur, rhs[..., None])[..., 0]
    step_b = (g_b - (h_ab.transpose(0, 2, 1) @ step_a[..., None])[..., 0]) / h_bb
    return np.concatenate([step_a, step_b], axis=1)
