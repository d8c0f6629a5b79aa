"""How many plates, and where they start: one plate from the centroid start (and the paper's
argmax), then, greedily, one more from the centroid of what the plates so far leave
unexplained, followed by a joint fit of all of them.

'auto' keeps a new plate only if the BIC improves: the drop of -2 log L, divided by the noise
correlation's inflation kappa = tr(C^2) / tr(C) (1 for counts), exceeds p ln(N / kappa) with
p = the plate's free parameters + 1 amplitude. -2 log L is measured in units of the residual
variance of the larger model: the noise's, or, where the larger model still misses the data by
more than the noise (Birge ratio B > 1, a real object is no plate), B times it, the same scale
the covariance uses. A spare plate that only absorbs model error lowers the residual by a
fraction of the misfit and fails; a second target, however faint (a target 1.4 times farther
returns ~1/4 of the signal, ~1/16 of its energy), lowers it by far more than the noise.

Where even the larger model does not explain the data (B above the 99.9 % point of its noise
distribution, chi^2_nu / nu with nu = N / kappa: a closed box shows two faces and more, which
plates describe only roughly), a plate more may just trade one misfit for another; it is then
kept only if it also carries at least `MIN_SHARE` of the fitted signal energy, as before. Photon
counts keep that share test always: at a few counts per bin the deviance has no chi^2 scale to
tell misfit from noise.
"""
from __future__ import annotations

import math

import numpy as np

from . import starts
from .fit import covariance, fit

SHORT_NFEV = 6
MIN_SHARE = 0.10


def best_of(problem, rows, free, final_nfev, fixed=None):
    """Short fits from the best candidate rows, then the best one to convergence."""
    prefix = [] if fixed is None else list(fixed)
    chosen = starts.best_starts(problem, rows, fixed, keep=3)
    short = [fit(problem, np.array(prefix + [p]), free, SHORT_NFEV) for p in chosen]
    best = min(short, key=lambda r: r.cost)
    return fit(problem, best.params, free, final_nfev)


def one_plate(problem, argmax_position, free, z0, final_nfev):
    centres = starts.start_centres(problem.obs, argmax_position, bool(free[2]), z0)
    return best_of(problem, starts.candidates(centres, problem.obs.laser), free, final_nfev)


def add_plate(problem, current, free, z0, final_nfev):
    """current + one plate started where the residual signal is."""
    cols = problem.columns(current.params)
    rest = problem.obs.y - problem.mean(cols, current.linear)
    if problem.obs.mode == "poisson":
        rest = rest + problem.obs.y[:, :5].mean(axis=1, keepdims=True)
    centres = starts.start_centres(problem.obs, None, bool(free[2]), z0, data=rest)
    rows = starts.candidates(centres, problem.obs.laser)
    joint = best_of(problem, rows, free, final_nfev, fixed=current.params)
    for _ in range(2):
        swept = sweep(problem, joint, free, final_nfev)
        if swept is joint:
            break
        joint = swept
    return joint


def sweep(problem, current, free, final_nfev):
    """Re-seat each plate in turn (yaw and size lattice around its centre, the others fixed),
    then refit all jointly: a plate that first grew to cover two targets' signals shrinks."""
    params = current.params.copy()
    for k in range(len(params)):
        others = np.delete(params, k, axis=0)
        rows = starts.candidates([params[k][:3]], problem.obs.laser)
        rows = np.concatenate([rows, params[k][None]])
        params[k] = starts.best_starts(problem, rows, others, keep=1)[0]
    again = fit(problem, params, free, final_nfev)
    return again if again.cost < current.cost else current


def kappa(obs) -> float:
    if obs.mode != "gauss":
        return 1.0
    return float(1.0 + 2.0 * np.sum(obs.rho[1:] ** 2))


def accepts(problem, before, after, free) -> tuple[bool, dict]:
    """Does `after` (one plate more) pass the BIC test, in units of its own residual variance?
    (Also reported: the share of the fitted signal energy the weakest plate carries.)"""
    obs = problem.obs
    k = kappa(obs)
    n_eff = max(after.n_residuals / k, 2.0)
    penalty = (int(np.count_nonzero(free)) + 1) * math.log(n_eff)
    birge, adequate = 1.0, False
    if obs.mode == "gauss":
        from scipy.stats import chi2
        birge = covariance(problem, after, free)[1]["birge_ratio"]
        adequate = birge <= chi2.ppf(0.999, n_eff) / n_eff
    gain = (before.cost - after.cost) / (k * max(1.0, birge))
    cols = problem.columns(after.params)
    energy = np.array([np.sum((a * c) ** 2) for a, c in zip(after.linear, cols)])
    share = float(energy.min() / max(energy.sum(), 1e-300))
    ok = gain > penalty and (adequate or share >= MIN_SHARE)
    return ok, {"bic_gain": gain - penalty, "share": share, "birge_after": birge,
                "explains_data": bool(adequate)}


def fit_targets(problem, est, argmax_position, free, z0):
    """The fit for est.targets plates (int or 'auto'), and what was tried."""
    current = one_plate(problem, argmax_position, free, z0, est.final_nfev)
    history = [{"targets": 1, "cost": current.cost}]
    wanted = est.targets if est.targets != "auto" else est.max_targets
    while len(current.params) < wanted:
        bigger = add_plate(problem, current, free, z0, est.final_nfev)
        entry = {"targets": len(bigger.params), "cost": bigger.cost}
        if est.targets == "auto":
            ok, why = accepts(problem, current, bigger, free)
            entry.update(why, accepted=ok)
            history.append(entry)
            if not ok:
                break
        else:
            history.append(entry)
        current = bigger
    return current, history
