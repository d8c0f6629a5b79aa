"""Plate or closed shape for one target (`closed_or_plate`): where the plate, re-seated, still
misses the data (criteria.misfit) or the depth probe finds a box behind it better, the closed
shapes (box, ellipsoid, cylinder, capsule) are fitted from starts around the plate and at the
centroid, and the one of lowest cost is kept where its one more parameter (depth) passes the BIC test."""
from __future__ import annotations

import math

import numpy as np

from ....core import progress
from ....core.tuning import EXPLAINED_MIN, MISFIT_BIRGE
from ..forward.likelihood import take_calls
from ..shapes import box, plate
from ..shapes.shape import CLOSED_SHAPES, name_of
from ..solve.covariance import covariance
from ..solve.fit import fit
from ..solve.lockstep import fit_together
from ..solve.records import Chosen, ShapeFit
from . import closed_search, depth
from .rivals import CENTRE_RIVALS_KEY, RIVAL_DISTANCE_M, RIVALS_KEY, rivals
from .closed_search import CLOSED_NFEV, MIN_CROSS_DEPTH_M
from .criteria import depth_gain, kappa, misfit
from .select import FINAL_ATOL, best_of

CLOSED = CLOSED_SHAPES  # the closed families tried (box, ellipsoid, cylinder, capsule)
# A plate that misses the data (misfit above MISFIT_BIRGE) and leaves more than this share of
# the signal unexplained gets no closed shapes (`beyond_closed`): twice what a closed shape
# may leave and still be reported (sanity: 1 - EXPLAINED_MIN)
NO_CLOSED_LEFT = 2.0 * (1.0 - EXPLAINED_MIN)


# Depths the closed fit is profiled at (its own depth d: d / 2, 2 d, d -/+ PROFILE_STEP_M),
# each an LM fit with the depth held and the front face as the start.
PROFILE_STEP_M = 0.3


def depth_profile(closed_problem, result, free_closed, final_nfev, unit) -> dict:
    """The closed fit's depth profiled (`PROFILE_STEP_M`): {depth_profile_sd_m: the depth's
    sd from the profile's secants, max |d_i - d| / sqrt(max(dchi2_i, 1)), dchi2 in `unit`s of
    cost (the BIC's: kappa times the fit's Birge ratio where it misses the data; a point
    within one unit, or cheaper, bounds the sd below by its distance), depth_profile: (depth,
    cost) pairs}. The
    Laplace sd holds where the cost is quadratic, and a closed object's depth seen from one
    side is not: a box fitted 0.44 m deep (truth 0.66, Laplace sd 0.07, centre 0.11 m off)
    costs 1.6 units more at 0.74 m (secant sd 0.24 m), and a cylinder seen by a vertical line
    of spots, fitted 0.20 m deep (sd 0.06, 0.16 m off, unwarned), 0.2 units more at 0.50 m.
    The answer keeps the fit (not refitted from a cheaper profile point): where the profile is
    this flat, its minimum is the noise's."""
    progress.stage("model fit: the closed shape's depth profiled")
    p = result.params[0]
    fitted = float(p[box.DEPTH])
    lowest = max(float(closed_problem.shape.LOWER[box.DEPTH]), MIN_CROSS_DEPTH_M)
    depths = sorted({round(max(lowest, v), 6) for v in (
        0.5 * fitted, 2.0 * fitted, fitted - PROFILE_STEP_M, fitted + PROFILE_STEP_M)})
    front, held = box.front_of(p), np.array(free_closed, bool)
    held[box.DEPTH] = False
    depths = [d for d in depths if abs(d - fitted) > 1e-3]
    # in lockstep (Gaussian data: one batch a round for all depths; the same answers)
    fits = fit_together(closed_problem, [box.from_plate(front, d)[None] for d in depths], held,
                        final_nfev)
    sd, profile = 0.0, []
    for d, r in zip(depths, fits):
        profile.append((d, float(r.cost)))
        sd = max(sd, abs(d - fitted) / math.sqrt(max((r.cost - result.cost) / unit, 1.0)))
    return {"depth_profile_sd_m": sd, "depth_profile": profile}


def centre_profile(closed_problem, result, free_closed, cov_matrix, final_nfev, unit
                   ) -> list[dict]:
    """The closed fit refitted with its centre held RIVAL_DISTANCE_M away on either side
    along its least certain direction (the centre covariance's principal axis, on the axes
    the layout sees) and along the line of sight from the laser spot (where a closed
    object's centre hides behind the face the spots see), the other parameters free:
    [{direction: 'least certain' or 'line of sight', offset_m, units}] (units: the cost
    above the fit's, in `unit`s as `rivals`; rivals.centre_note says it within RIVAL_UNITS).
    The covariance is the fit's curvature at its minimum; on sparse counts the cost is flat
    or has other basins a few units up: counts draw 26's ellipsoid (Fisher sds 0.013-0.047
    m, 0.44 m off) costs 3.2 units more with its centre 0.15 m along its least certain
    direction. Photon counts only (closed_or_plate): on the closed family's 200 Gaussian
    draws it warned no failure the notices did not already, at +15 % of the time
    (docs/model-estimator.md, "Uncertainty")."""
    progress.stage("model fit: the closed shape's centre held aside")
    p = np.asarray(result.params[0], float)
    sd2 = np.diag(np.asarray(cov_matrix, float))[:3]
    seen = np.isfinite(sd2) & np.asarray(free_closed, bool)[:3]
    if not seen.any():
        return []
    block = np.asarray(cov_matrix, float)[:3, :3][np.ix_(seen, seen)]
    least = np.zeros(3)
    least[seen] = np.linalg.eigh(block)[1][:, -1]
    sight = p[:3] - np.mean(np.reshape(closed_problem.obs.laser, (-1, 3)), axis=0)
    sight[~seen] = 0.0
    directions = [("least certain", least)]
    reach = np.linalg.norm(sight)
    if reach > 0 and abs(least @ sight) < 0.9 * reach:  # not the least certain axis again
        directions.append(("line of sight", sight / reach))
    held = np.array(free_closed, bool)
    held[:3] = False
    starts, labels = [], []
    for name, v in directions:
        for sign in (-1.0, 1.0):
            q = p.copy()
            q[:3] += sign * RIVAL_DISTANCE_M * v
            starts.append(q[None])
            labels.append((name, sign * RIVAL_DISTANCE_M))
    fits = fit_together(closed_problem, starts, held, final_nfev)
    return [{"direction": name, "offset_m": off, "units": (float(r.cost) - result.cost) / unit}
            for (name, off), r in zip(labels, fits)]


RESEAT_YAWS = np.radians([-40.0, -20.0, 20.0, 40.0])
RESEAT_WIDTHS = (0.6, 1.0, 1.6)  # times the fitted width


def reseat_plate(problem, plate_result, free, final_nfev):
    """The plate refitted from a lattice of yaws and widths around its own fit (the better
    result of the two). With collinear spots width and yaw trade against each other, and a
    far plate (the 0.3 x 1.6 m one at (5, 1)) converged 26 degrees off its yaw with 0.6 of its
    width: Birge ratio 7, where the lattice reaches 0.89 (and the closed shapes, whose starts
    include those yaws, had fitted a 0.1 m-deep box 0.05 m behind the plate). So a misfit plate
    is re-seated before anything closed is tried."""
    q = plate_result.params[0]
    rows = [q.copy()]
    for dyaw in RESEAT_YAWS:
        for scale in RESEAT_WIDTHS:
            p = q.copy()
            p[plate.WIDTH], p[plate.YAW] = p[plate.WIDTH] * scale, p[plate.YAW] + dyaw
            rows.append(p)
    result = best_of(problem, np.array(rows), free, final_nfev)
    return result if result.cost < plate_result.cost else plate_result


def closed_fits(problem, plate_result, free, final_nfev, smooth=None) -> tuple[list, bool]:
    """Each closed family (CLOSED) fitted by the pooled search (model.policy.closed_search):
    ([(problem, result, free)], raced). With `smooth` (counts: the
    same detectors' Gauss-filtered frame), where the best of them misses the counts but not
    by so much that no closed shape is their model (`worth_racing`), each family is sought on
    the filtered frame too, as counts' search is (model.filtered_search), and refitted on
    `problem` from that answer; the lower counts cost of the two stands (raced: whether it
    was). The plate's problem counts every forward call made for it."""
    progress.stage(f"model fit: closed shapes (boxes, ellipsoids, cylinders; "
                   f"{len(problem.obs.spots):,} histograms)")
    fits = closed_search.search(problem, plate_result, free, final_nfev, atol=FINAL_ATOL)
    raced = smooth is not None and worth_racing(*min(fits, key=lambda f: f.result.cost))
    if raced:
        plate_there = fit(smooth, plate_result.params, free, final_nfev)
        found, _ = closed_fits(smooth, plate_there, free, final_nfev)  # in CLOSED's order
        take_calls(problem, smooth)
        both = []
        for (closed_problem, own, free_closed), (_, there, _) in zip(fits, found):
            again = fit(closed_problem, there.params, free_closed, CLOSED_NFEV * final_nfev,
                        atol=FINAL_ATOL)
            both.append(ShapeFit(closed_problem, again if again.cost < own.cost else own,
                                 free_closed))
        fits = both
    for closed_problem, _, _ in fits:
        take_calls(problem, closed_problem)
    return fits, raced


def worth_racing(closed_problem, result, free_closed) -> bool:
    """Should counts' closed fits also be sought on the filtered frame? Where the best one
    misses the counts (criteria.misfit: the deviance per degree of freedom above its 99.9 %
    point), but by at most MISFIT_BIRGE (above it no closed shape is the data's model, and the
    sanity check treats it so: CC-SOCR's one-laser readings, ~400, where the race took 4 -> 9 s
    for the same rejected box). On the 200 counts draws, raced only there: 44 failures (p90
    0.302 m) at +5 % of the time."""
    inadequate, birge = misfit(closed_problem, result, free_closed, {})
    return inadequate and birge <= MISFIT_BIRGE


def beyond_closed(problem, plate_result, birge) -> float | None:
    """The share of the signal the plate leaves unexplained (1 - explained, as
    sanity.fit_checks) where no closed shape can be reported instead, else None: its misfit
    above MISFIT_BIRGE and more than NO_CLOSED_LEFT left. A closed shape tried there is kept
    only if it cuts the misfit below MISFIT_BIRGE or the share below 1 - EXPLAINED_MIN
    (sanity.closed_centre_guessed rejects it otherwise): closed fits to simulated closed
    targets leave 3e-6 to 5e-5 (core/tuning.py), their plates at most 2.4 % (14 closed draws),
    and CC-SOCR's "4" as one laser (plate misfit 420-480, 29-34 % left) had its closed fits
    rejected or beaten by the plate after 2-4 s of the search, twice with the late copies
    (docs/model-estimator.md, "Speed of small captures")."""
    from .sanity import explained_share
    share = explained_share(problem, plate_result)
    left = 0.0 if share is None else 1.0 - share
    return left if birge > MISFIT_BIRGE and left > NO_CLOSED_LEFT else None


def box_behind(problem, plate_result, plate_cov) -> bool:
    """Would a box behind this plate, which fits the data, explain them better
    (depth.probe)? The probe's findings go into plate_cov's info."""
    seen = depth.probe(problem, plate_result, kappa(problem.obs))
    plate_cov.info.update(depth_sd_m=seen["depth_sd_m"], box_probe_better=seen["box_better"])
    return seen["box_better"]


def closed_or_plate(problem, plate_result, free, final_nfev, plate_cov, closed="auto",
                    probe_depth=True, tried=False, smooth=None, sanity=False, beyond=False):
    """Plate or closed shape for one target. The closed shapes (CLOSED) are fitted only where
    the plate, re-seated (`reseat_plate`), still misses the data (`misfit`), a box behind it
    would do better (`box_behind`), tried (the caller's probe on more detectors said so:
    model.subset) or closed=True; the one of lowest cost (they share the parameters) is kept
    where its one more parameter (depth) passes the BIC test in units of its own residual
    variance (as `accepts`). plate_cov: covariance(...) of the plate. smooth: None, or
    (photon counts) the same detectors' Gauss-filtered frame, where the closed shapes are
    also sought (`closed_fits`). sanity: the estimator's sanity check is on (`profiled`);
    beyond: with it, no closed search where `beyond_closed` rules every closed shape out
    (model.subset: few detectors only; on many, a doomed closed shape on the subset ends the
    fit with the argmax, which a plate would not: CC-SOCR's 4,096 points 8 -> 22 s).
    Returns the chosen model's fit and covariance (a Chosen)."""
    inadequate, birge = misfit(problem, plate_result, free, plate_cov.info)
    if inadequate and closed is not True:  # a misfit plate is re-seated first
        reseated = reseat_plate(problem, plate_result, free, final_nfev)
        if reseated is not plate_result:
            plate_result, plate_cov = reseated, covariance(problem, reseated, free)
            inadequate, birge = misfit(problem, plate_result, free, plate_cov.info)
            plate_cov.info.update(plate_reseated=True)
    plate_cov.info.update(plate_birge_ratio=birge, closed_tried=False)
    if beyond and closed == "auto" and sanity and (
            left := beyond_closed(problem, plate_result, birge)):
        plate_cov.info.update(closed_skipped_left=left)  # depth.unseen_note says so
        return Chosen(problem, plate_result, free, plate_cov)
    if closed == "auto" and not inadequate and probe_depth and not tried:
        inadequate = box_behind(problem, plate_result, plate_cov)
    if closed is False or (closed == "auto" and not inadequate and not tried):
        return Chosen(problem, plate_result, free, plate_cov)
    fits, raced = closed_fits(problem, plate_result, free, final_nfev, smooth)
    shaped, result, free_shaped = min(fits, key=lambda f: f.result.cost)
    shaped_cov = covariance(shaped, result, free_shaped)
    gain, unit = depth_gain(problem.obs, plate_result.cost, shaped, result, free_shaped,
                            shaped_cov.info)
    why = {"plate_birge_ratio": birge, "closed_tried": True, "closed_raced": raced,
           "closed_bic_gain": gain,
           "closed_costs": {name_of(f.problem.shape): f.result.cost for f in fits}}
    if closed is not True and gain <= 0:  # the plate stands
        plate_cov.info.update(why)
        return Chosen(problem, plate_result, free, plate_cov)
    shaped_cov.info[RIVALS_KEY] = rivals(
        [(name_of(f.problem.shape), f.result) for f in fits], name_of(shaped.shape), result, unit)
    if profiled(shaped, result, free_shaped, shaped_cov, sanity):
        shaped_cov.info.update(depth_profile(shaped, result, free_shaped, final_nfev, unit))
        if shaped.obs.mode == "poisson":  # counts: the Fisher sds are not the spread
            shaped_cov.info[CENTRE_RIVALS_KEY] = centre_profile(
                shaped, result, free_shaped, shaped_cov.matrix, final_nfev, unit)
    shaped_cov.info.update(why)
    return Chosen(shaped, result, free_shaped, shaped_cov)


def profiled(shaped, result, free_shaped, shaped_cov, sanity: bool) -> bool:
    """Is the chosen closed fit's depth profiled? Its sd is read only by depth.unseen_note
    (the answer's depth notice, and sanity.closed_centre_guessed's `depth_unseen`), so not
    where the sanity check will reject the fit whatever its depth's sd: a misfit above
    MISFIT_BIRGE that leaves more than 1 - EXPLAINED_MIN of the signal unexplained
    (CC-SOCR's 3 points as one laser: 0.9 of a 5.7 s locate, for an ellipsoid rejected)."""
    if not sanity:
        return True
    from .sanity import closed_centre_guessed, fit_checks
    checks = fit_checks(shaped, result, free_shaped, *shaped_cov)
    return not closed_centre_guessed(name_of(shaped.shape), dict(checks, depth_unseen=False))
