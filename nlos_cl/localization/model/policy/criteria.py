"""The tests the model selection applies to a fit (policy.select, closed, subset, warm): the
noise correlation's information scale (`kappa`), whether a fit misses the data (`misfit`),
whether one plate more is worth its parameters (`accepts`), whether plates lie apart
(`separate`), and the signal energy each fitted plate explains.

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
tell misfit from noise. Any plate more, apart or not, must carry `MIN_ANY_SHARE` of the energy:
below it a return is no stronger than the instrument tails and model error of the bright ones.
"""
from __future__ import annotations

import math

import numpy as np

from ....core.constants import TINY
from ....core.stats import chi2_quantile
from ..shapes import plate
from ..solve.covariance import covariance

# The least share of the fitted energy a plate more must carry where the larger model still
# misses the data and the plates touch (module docstring).
MIN_SHARE = 0.10
# The least share of the fitted energy any plate more must carry (a far plate apart from the
# others needs no MIN_SHARE). The weakest true target of 200 multi draws (targets 0.2-1.2 m,
# 1/r^4) carried 1.0e-4 of the noise-free filtered energy, 10 more below 5e-4; the residual
# of two squares' mutual shadow that the shadow model leaves (Birge 3.2) was taken up by a
# 1.16 x 0.04 m strip 0.11 m from the wall carrying 4.8e-6 (tests/localization/model/test_model_selection.py).
# A return 1e-5 of the energy is ~0.3 % of the peak: the level of a measured instrument
# response's tail and of the model's own error on the bright targets.
MIN_ANY_SHARE = 1e-5
APART_GAP_M = 0.2
# plates whose surfaces lie this far apart are two objects, however they overlap from the
# wall: more than any box or cabinet of the scenario ranges shows between faces it returns from
SURFACES_APART_M = 0.5


def kappa(obs) -> float:
    if obs.mode != "gauss":
        return 1.0
    return float(1.0 + 2.0 * np.sum(obs.rho[1:] ** 2))


def accepts(problem, before, after, free) -> tuple[bool, dict]:
    """Does `after` (one plate more) pass the BIC test, in units of its own residual variance?
    (Also reported: the share of the fitted signal energy the weakest plate carries.)"""
    gain, birge, adequate = bic_gain(problem, before, after, free)
    energy = plate_energies(problem, after)
    share = float(energy.min() / max(energy.sum(), TINY))
    # a plate more that adds an object: apart from every plate, or beside two plates that
    # touch (a closed target's faces); all pairs apart alone refused a far box's plate
    # beside a person's two (scenario draw 89)
    apart = objects(after.params) > objects(before.params)
    ok = gain > 0 and share >= MIN_ANY_SHARE and (adequate or share >= MIN_SHARE or apart)
    return ok, {"bic_gain": gain, "share": share, "birge_after": birge,
                "explains_data": bool(adequate), "apart": apart,
                "cost_drop": float((before.cost - after.cost) / max(before.cost, TINY))}


def bic_gain(problem, before, after, free, birge=None) -> tuple[float, float, bool]:
    """(the drop of -2 log L from `before` to `after`, one plate more, in units of kappa times
    the larger fit's Birge ratio, less the plate's penalty; that Birge ratio; whether the larger
    fit explains the data). birge: the larger fit's, where known (saves its covariance)."""
    obs = problem.obs
    k = kappa(obs)
    n_eff = max(after.n_residuals / k, 2.0)
    penalty = (int(np.count_nonzero(free)) + 1) * math.log(n_eff)
    adequate = False
    if obs.mode == "gauss":
        if birge is None:
            birge = covariance(problem, after, free)[1]["birge_ratio"]
        adequate = birge <= chi2_quantile(0.999, n_eff) / n_eff
    birge = 1.0 if obs.mode != "gauss" else birge
    return (before.cost - after.cost) / (k * max(1.0, birge)) - penalty, birge, adequate


def objects(params) -> int:
    """How many separate objects the plates are (`object_labels`)."""
    return len(set(object_labels(params)))


def object_labels(params) -> list:
    """Per plate, the object it belongs to: plates that touch (neither `separate` as a pair
    nor their surfaces SURFACES_APART_M apart), and plates that touch those, share one."""
    p = np.asarray(params, float)
    group = list(range(len(p)))
    for i in range(len(p)):
        for j in range(i + 1, len(p)):
            if not (separate(p[[i, j]]) or surfaces_apart(p[i], p[j])):
                gi, gj = group[i], group[j]
                group = [gi if g == gj else g for g in group]
    return group


def surfaces_apart(a, b, samples: int = 9) -> bool:
    """Do plates a and b (x, y, z, width, height, yaw) have their surfaces' nearest points
    farther apart than SURFACES_APART_M? An occluder 0.8 m in front of the target it half
    hides overlaps it as seen from the wall (`separate` calls the pair one object); two faces
    of one box, or a plate and a delayed background's plate close behind it, still touch."""
    grid = np.linspace(-0.5, 0.5, samples)
    u, v = (g.ravel() for g in np.meshgrid(grid, grid))
    pts = []
    for x, y, z, w, h, yaw in (np.asarray(a, float)[:6], np.asarray(b, float)[:6]):
        across = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
        pts.append(np.array([x, y, z]) + np.outer(u * w, across) + np.outer(v * h, [0, 0, 1.0]))
    return bool(np.linalg.norm(pts[0][:, None] - pts[1][None], axis=2).min() > SURFACES_APART_M)


def separate(params) -> bool:
    """Do the plates lie apart, each farther from every other than their half-diagonals plus
    APART_GAP_M? Plates that touch may be one closed object's faces (a box seen corner-on),
    where a plate more trades one misfit for another; plates apart are separate objects, and a
    weak far one (1/r^4: a target 2.2x farther returns 1/25 of the signal, 1/600 of its
    energy) then needs no MIN_SHARE of the energy, only the BIC gain."""
    p = np.asarray(params, float)
    half = 0.5 * np.hypot(p[:, plate.WIDTH], p[:, plate.HEIGHT])
    for i in range(len(p)):
        for j in range(i + 1, len(p)):
            if np.linalg.norm(p[i, :3] - p[j, :3]) <= half[i] + half[j] + APART_GAP_M:
                return False
    return True


def misfit(problem, result, free, cov_info) -> tuple[bool, float]:
    """Does the fit miss the data by more than the noise? The Birge ratio (from
    `covariance`'s info) above the 99.9 % point of chi^2_nu / nu, nu = N / kappa; counts: the
    deviance per degree of freedom, same test."""
    n_eff = max(result.n_residuals / kappa(problem.obs), 2.0)
    birge = cov_info.get("birge_ratio")
    if birge is None:
        birge = result.cost / max(result.n_residuals - int(np.count_nonzero(free)) - 1, 1)
    return birge > chi2_quantile(0.999, n_eff) / n_eff, float(birge)


def depth_gain(obs, before_cost, closed_problem, result, free, info, depths=1):
    """(gain, unit): the BIC gain of a closed fit's `depths` more parameters (one depth a
    target) over a fit of cost `before_cost` on the same data, -2 log L counted in `unit` =
    kappa times its own Birge ratio where it misses the data (as `accepts`); above 0 the
    closed shapes are kept (policy.closed, policy.closed_many)."""
    k = kappa(obs)
    unit = k * max(1.0, misfit(closed_problem, result, free, info)[1])
    log_n = math.log(max(result.n_residuals / k, 2.0))
    return (before_cost - result.cost) / unit - depths * log_n, unit


DEAD_SHARE = 1e-4  # of the fitted signal energy: a target 2.2x farther carries ~1/600


def dead_plates(problem, result) -> np.ndarray:
    """(K,) bool: plates whose fitted amplitude is 0 or that carry less than DEAD_SHARE of
    the signal energy the fit explains."""
    energy = plate_energies(problem, result)
    return (result.linear[:len(energy)] <= 0) | (
        energy < DEAD_SHARE * max(float(energy.sum()), TINY))


def plate_energies(problem, result) -> np.ndarray:
    """(K,) the signal energy each fitted plate explains: sum of (amplitude x column)^2."""
    cols = problem.columns(result.params)
    lin = np.asarray(result.linear[:len(cols)], float)
    return np.einsum("k,kdn->k", lin ** 2, cols ** 2)


def support(problem, result, free, birge) -> list:
    """Per plate of a fit with two or more, the BIC gain of keeping it (the test `accepts`
    applies to a plate more, run backwards: the cost without it, the others' amplitudes
    profiled, against the fit's, in units of its residual variance, less the plate's
    penalty): below 0 the data do not hold that plate. A fixed number of plates warm-started
    from tracks places one even where its target has gone (a walker's turn: a plate at the
    old track's prediction kept that track alive for 5 frames, tracking.births)."""
    params = np.asarray(result.params, float)
    if len(params) < 2 or problem.obs.mode != "gauss":
        return [None] * len(params)
    k = kappa(problem.obs)
    n_eff = max(result.n_residuals / k, 2.0)
    penalty = (int(np.count_nonzero(free)) + 1) * math.log(n_eff)
    scale = k * max(1.0, float(birge or 1.0))
    out = []
    for j in range(len(params)):
        cols = problem.columns(np.delete(params, j, axis=0))
        r = problem.residual(cols, problem.linear(cols))
        out.append(float((float(r @ r) - result.cost) / scale - penalty))
    return out
