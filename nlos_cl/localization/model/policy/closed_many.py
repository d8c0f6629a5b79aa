"""Closed shapes for a fit of several targets: where K >= 2 plates that lie apart
(criteria.separate) miss the data, each closed family (box, ellipsoid, cylinder, capsule) is
fitted to all K targets at once, started from the plates
(each target in turn from START_DEPTHS behind its plate, short fits, the cheapest kept),
and the family of lowest cost, fitted to convergence, replaces the plates where its K more parameters (the depths)
pass the BIC test, as one target's closed shape does (policy.closed.closed_or_plate).

Why: a person or a box among several targets was fitted as a plate on its front surface, its
reported centre the surface's, 0.25-0.42 m from the object's (the scenario suite's multi draws
17, 33, 57, 65, 81). A plate target in the closed model is a shape of the least depth (box:
0; ellipsoid, cylinder: 0.04 m), so one family serves a mixed scene. The K closed shapes do
not shadow each other in this model (the plates' search does not either: policy.select).
"""
from __future__ import annotations

import numpy as np

from ..shapes import box
from ..shapes.shape import CLOSED_SHAPES, name_of
from ..solve.covariance import covariance
from ..solve.fit import fit
from ..solve.records import Chosen
from . import starts
from ..solve.lockstep import fit_together
from .closed_search import CLOSED_NFEV, SHORT_NFEV, closed_free
from .criteria import depth_gain, kappa, misfit, objects
from .depth import DEPTH_SDS_KEY, depth_sds
from .rivals import RIVALS_KEY, rivals
from .select import FINAL_ATOL

# Depths (m) each target's closed starts are tried at behind its plate's face: a plate (the
# family's least), a person's or a crate's depth, a cabinet's or a car's side
START_DEPTHS = (0.0, 0.1, 0.3, 0.6)


def several(est, problem, plates: Chosen, argmax_position, held, smooth, history) -> Chosen:
    """The answer for K >= 2 fitted plates (`plates`, a Chosen) of estimator `est`: closed
    shapes for all of them where the data ask for them (`closed_instead`); with targets='auto'
    then one closed target instead where it explains the data (policy.subset's
    one_closed_instead, recorded in `history`)."""
    chosen = closed_instead(problem, plates, est.final_nfev)
    if est.targets != "auto":
        return chosen
    from .subset import one_closed_instead
    single = one_closed_instead(est, problem, argmax_position, plates.free, held, chosen, smooth)
    history.append({"targets": 1, "closed_instead": single is not chosen})
    return single


def closed_instead(problem, plates: Chosen, final_nfev) -> Chosen:
    """`plates` (K >= 2 plates, a Chosen), or the closed family fitted to all K targets where
    the plates miss the data (criteria.misfit) and that family's depths pass the BIC test
    (in units of its own residual variance, as closed_or_plate's)."""
    result, free = plates.result, plates.free
    inadequate, birge = misfit(problem, result, free, plates.cov.info)
    # only plates that lie apart (not the surfaces test of criteria.objects: an occluder
    # overlaps its target as seen, and the closed shapes model no shadows): where they touch
    # (targets crossing, one object's faces) the misfit is their meeting's, which closed
    # shapes absorbed:
    # two 0.3 m squares crossing lost a track (tests/tracking/test_tracking_end_to_end.py)
    tried = inadequate and objects(result.params) == len(result.params)
    plates.cov.info.update(plate_birge_ratio=birge, closed_tried=bool(tried))
    plates.cov.info[DEPTH_SDS_KEY] = depth_sds(problem, result, kappa(problem.obs))
    if not tried:
        return plates
    shorts = [_family(problem, shape, result, free) for shape in CLOSED_SHAPES]
    closed, start, free_closed = min(shorts, key=lambda f: f[1].cost)
    fitted = fit(closed, start.params, free_closed, CLOSED_NFEV * final_nfev, atol=FINAL_ATOL)
    fits = [(closed, fitted) if f[0] is closed else f for f in shorts]
    cov = covariance(closed, fitted, free_closed)
    fitted, cov = _flat_where_unneeded(problem, closed, fitted, free_closed, cov, final_nfev)
    gain, unit = depth_gain(problem.obs, result.cost, closed, fitted, free_closed, cov.info,
                            depths=len(result.params))
    why = {"closed_tried": True, "closed_bic_gain": gain,
           "closed_costs": {name_of(f[0].shape): f[1].cost for f in fits}}
    if gain <= 0:
        plates.cov.info.update(why)
        return plates
    # the other families' fits here are short (`_family`): their rivals are the fewer
    cov.info.update(why, plate_birge_ratio=birge, **{RIVALS_KEY: rivals(
        [(name_of(f[0].shape), f[1]) for f in fits], name_of(closed.shape), fitted, unit)})
    flat = _at_least_depth(closed.shape, fitted.params)
    return Chosen(closed, fitted, free_closed, cov._replace(
        matrix=given_depths(cov.matrix, flat, closed.shape.N_PARAMS)))


def _flat_where_unneeded(problem, closed, fitted, free, cov, final_nfev):
    """(fit, covariance): `fitted` with each target whose depth the data do not ask for
    (its depth's BIC gain, criteria.depth_gain with one parameter, <= 0 against the fit with
    that depth held at the family's least) held there: a plate. The K depths pass or fail the
    BIC test together; one closed object among plates gave every plate a depth (scenario
    occluders draw 47: the occluder, a plate, fitted 0.11 m deep, its centre 0.007 -> 0.057 m
    off). Targets are tried shallowest first; each held one stays held."""
    least = float(closed.shape.LOWER[box.DEPTH])
    mean = np.array(fitted.params, float)
    sd = np.full(mean.shape, np.inf)
    for k in np.argsort(mean[:, box.DEPTH]):
        if mean[k, box.DEPTH] <= least + FLAT_M:
            continue
        rows, held = np.array(fitted.params, float), sd.copy()
        rows[k, box.DEPTH], held[k, box.DEPTH] = least, HELD_DEPTH_SD_M
        mean[k, box.DEPTH] = least
        pinned = fit(closed, rows, free, final_nfev, prior=(mean, held), atol=FINAL_ATOL)
        gain, _ = depth_gain(problem.obs, pinned.cost, closed, fitted, free, cov.info)
        if gain > 0:
            mean[k, box.DEPTH] = fitted.params[k, box.DEPTH]
            continue
        sd = held
        fitted, cov = pinned, covariance(closed, pinned, free)
    return fitted, cov


HELD_DEPTH_SD_M = 1e-4  # a depth held at the family's least by the fit's prior


def _at_least_depth(shape, params) -> np.ndarray:
    """(K,) bool: targets fitted at the family's least depth (a plate among closed objects)."""
    return np.asarray(params)[:, box.DEPTH] <= float(shape.LOWER[box.DEPTH]) + FLAT_M


FLAT_M = 0.01  # within this of the least depth a fitted target is a plate


def given_depths(cov, which, n) -> np.ndarray:
    """cov (K n square) conditioned on the depths of the targets `which` (Schur complement):
    a target the fit left at the least depth is a plate, its depth held at the bound, where the
    Laplace approximation (a bound is no quadratic minimum) would move its centre along the
    normal with the depth it cannot have (one plate among a box: sd 0.38 m across, 0.004 m as
    a plate)."""
    held = [k * n + box.DEPTH for k in np.flatnonzero(which)]
    finite = [i for i in held if np.isfinite(cov[i, i]) and cov[i, i] > 0]
    if not finite:
        return cov
    out = np.array(cov, float)
    keep = [i for i in range(len(out)) if i not in held and np.isfinite(out[i, i])]
    a, b = np.ix_(keep, finite), np.ix_(finite, finite)
    out[np.ix_(keep, keep)] -= out[a] @ np.linalg.solve(out[b], out[a].T)
    for i in held:
        out[i, :], out[:, i] = 0.0, 0.0
    return out


def _family(problem, shape, plates, free):
    """(problem, short result, free) of closed family `shape` for every target of `plates`:
    each target in turn started at START_DEPTHS behind its plate (the others where the last
    short fits left them), SHORT_NFEV evaluations from each, the cheapest kept. (One start per
    target chosen by one forward call each ran into a shallow minimum: a 0.6 m box's depth
    stalled at 0.79 m, cost 37x the truth's; from 0.1, 0.3 or 0.6 m it is reached.)"""
    from ..forward.host_shapes import shape_problem
    closed = shape_problem(problem, shape)
    free_closed = closed_free(free)
    least = float(shape.LOWER[box.DEPTH])
    rows = np.array([box.from_plate(q, least) for q in plates.params])
    best = None
    for k, q in enumerate(plates.params):
        tried = []
        for d in START_DEPTHS:
            again = rows.copy()
            again[k] = box.from_plate(q, max(least, d))
            tried.append(again)
        shorts = fit_together(closed, tried, free_closed, SHORT_NFEV)
        best = min(shorts, key=lambda r: (not starts.plausible(r.linear, len(rows)), r.cost))
        rows = best.params.copy()
    return closed, best, free_closed
