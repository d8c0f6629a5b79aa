"""Warm-started fits: a frame's model fit started from given plate rows (a tracker's previous
fit, moved to its predicted position) instead of from the data alone.

The cold fit (model.select) spends ~120-200 model evaluations on finding the basin:
the centroid start, a lattice of 20-40 yaws and sizes, three short fits, then the final
Levenberg-Marquardt fit. Where the previous frame's plate is known and the target moved a few
cm, the start is already in the basin, so only the final fit runs, with `warm_nfev`
evaluations (stopping on a statistical scale, WARM_ATOL), then the covariance (the same
sandwich and Birge-ratio calibration as a cold fit, its derivatives the solver's last
Jacobian: REUSE_JACOBIAN), on the estimator's `problem` (the host's
batched model for up to HOST_DETECTORS detectors with model_on='auto', as a cold fit).

Fallback: where the warm fit misses the data (the Birge ratio above the 99.9 % point of its
noise distribution: `criteria.misfit`, the test that also sends a cold fit on to the closed
shapes), the start was wrong (another basin, a target that turned or changed shape) and the
estimator runs the cold fit, keeping the warm one where the cold fit costs more (a shadowed
plate misses the data from any start: crossing draw 7 frame 13, warm Birge 7.9, cold 20). A fit that explains the data but lands far from where the
caller expected is the caller's to judge (the tracker's gate: nlos_cl.tracking.warm).
"""
from __future__ import annotations

import numpy as np

from ....core.errors import require
from ....core.tuning import HIDDEN_SHARE
from ...fit_result import HIDDEN_SD_KEY, HIDDEN_SHARE_KEY
from ..shapes import plate
from ..shapes.shape import SHAPES
from ..solve.covariance import covariance
from ..solve.fit import fit
from ..solve.records import Chosen, Fitted

# Stop when a step's predicted cost decrease (cost = chi^2 / 2 for whitened residuals, or the
# deviance / 2) is below this: what is left moved the centre by <= 0.015 sd (starts 0.5-4 sd
# off, paper's scene, 10 dB; 0.005 took 1-3 more evaluations for ~0.005 sd). The cold fit's
# relative ftol instead waits through rejected steps for the last ~1e-4 of cost, which
# finite-difference Jacobians cannot find.
WARM_ATOL = 0.05
# Initial LM damping (x max diag J'J) of a warm fit: the start is in the basin, so nearly
# Gauss-Newton steps are taken at once. Stream bench frames: 25.9 ms a frame, positions within
# 0.08 mm of the cold fit's default damping (1e-4). (Cold fits keep 1e-4: from far starts 1e-6
# jumped basins.)
WARM_TAU = 1e-6
# The warm fit's covariance from the solver's last Jacobian (model.covariance's `reuse`)
# instead of new derivatives: paper-scene tracker 10.59 ms a frame (12.65 with new ones); sds
# within the forward differences' ~2-5 % of the analytic ones (docs/model-estimator.md,
# "Uncertainty").
REUSE_JACOBIAN = True
# The warm fit steps each plate's width and yaw as its width vector (model.width_vectors:
# the data's width-yaw valley is straight there): stream bench 11.73 ms a frame against
# 12.95 in (width, yaw). Cold fits keep (width, yaw): their frames' median moved < 2 %.
WIDTH_VECTORS = True
# model.lm's best-gain stop (atol on the Jacobian's Gauss-Newton step: no trial step, no
# Jacobian made only to learn that the fit is done) for one plate; plates that may shadow
# each other keep the plain test (the step just tried): past a shadow's edge the quadratic
# model is no guide (crossing draw 15, seed 2201, a half-hidden plate: 0.011 -> 0.174 m RMS
# with it). Stream bench, one plate: 16.7 model calls a frame against 19.0.
BEST_GAIN_PLATES = 1
# model.fit's `speculate` (a residual's plate and its Jacobian's stepped plates in one host
# call) for one plate: 91 % of a warm fit's residual points are asked for a Jacobian next
# (stream bench: 219 of 240). Cold fits do without it: their short fits' last point and
# rejected trials left 34 % of it unused (lockstep already pairs the fits' calls).
SPECULATE = True


# A warm fit that misses the data after its whole budget (warm_nfev) is continued from where
# it stopped with this many times the budget before the cold fit is asked for: a plate that
# moved 0.1 m from a start with no velocity yet (docs/scenes/walk.yaml frame 1) stopped
# 0.05 m short at Birge 2.06 after 10 evaluations and settled at 1.62 after 13, where the cold
# fit it went to cost 1.6 s CPU (the closed search) for the same plate.
CONTINUE_NFEV = 2


# The last fitted rows are tried where the prediction misses and they lie this far from it
# (closer, the second fit would start where the first did).
RETRY_M = 0.02


def warm_or_retry(est, obs, prior, free, held, backend=None):
    """warm_fit's (fitted, info, missed) from the first start that explains the data, in turn:
    the Prior's rows; the same with late copies of the light where the cold fit kept them
    (Prior.late); the measured rows (the last fit, before the motion model moved it). missed:
    the cheapest miss (the cold fit's rival); info and the timings count every fit tried.
    - Late copies: without them a person's cylinder started at the cold answer on the same
      frame missed (Birge ratio 2.6 against 1.8; 48 from 5 cm off); tried second, as they
      double a fit's cost and a plate's warm fit rarely needs them (docs/scenes/walk.yaml:
      36 -> 70 ms a frame with them first, the same answers).
    - The last fit: a velocity learnt from a poor measurement sent a person's predictions
      0.3-0.5 m out of the basin (Birge ratio ~5,000: no overlap, no gradient, LM stopped at
      its start) while the last fit lay within one frame's motion."""
    from dataclasses import replace
    from ..forward.late import BANK
    shape = None if prior.shape == "plate" else prior.shape
    args = (free, held, backend, checked_sizes(prior, len(prior.rows)), prior.misfit, shape)
    rows = start_rows(est, prior.rows, shape)
    late = replace(obs, late=BANK) if prior.late and obs.late is None else None
    tries = [(rows, obs, "prior")] + ([(rows, late, "prior, late copies")] if late else [])
    if prior.measured is not None:
        last = start_rows(est, prior.measured, shape)
        if np.max(np.linalg.norm(last[:, :3] - rows[:, :3], axis=1)) >= RETRY_M:
            tries.append((last, late or obs, "last fit"))
    calls, model_s, best = 0, 0.0, None
    for start, data, name in tries:
        fitted, info, missed = warm_fit(est, data, start, *args)
        info = dict(info, start=name)
        done = fitted or missed
        calls, model_s = calls + done.problem.calls, model_s + done.problem.model_s
        done.problem.calls, done.problem.model_s = calls, model_s  # every fit tried counted
        if fitted is not None:
            return fitted, dict(info, forward_calls=calls), None
        if best is None or missed.result.cost < best[1].result.cost:
            best = (info, missed)
    best[1].problem.calls, best[1].problem.model_s = calls, model_s
    return None, dict(best[0], forward_calls=calls), best[1]


def warm_fit(est, obs, rows, free, held, backend=None, sizes=None, floor=None, shape=None):
    """(fitted, info, missed): a Fitted as ModelEstimator._cold returns it, or None where the
    warm fit misses the data (the caller then fits cold, and keeps `missed`, the misfit warm
    fit's Fitted, if the cold fit costs more); info: what was tried
    (details['warm_start']). sizes: None or (size, sd), each (K, 2) (Prior.size, size_sd):
    the sizes a plate the others partly hide starts from and is held to (`size_prior`).
    floor: None, or the Birge ratio the cold fit of these targets last reached (Prior.misfit):
    the warm fit misses only where it misses by more than that (`misses`). shape: None (plate
    rows), or a closed family's name (`closed_warm_fit`)."""
    from .closed import closed_or_plate
    # an axis the spots cannot see: held on the search plane, as a cold fit holds it
    rows = held.put(rows)
    problem = est.problem(obs, est.backend or backend)
    if shape is not None:
        return closed_warm_fit(est, problem, rows, free, shape, floor)
    prior = size_prior(problem, rows, sizes)
    if prior is not None:
        rows = prior[0]  # the hidden plates start at their known size
    result, cov, (inadequate, birge, floored), nfev = _settled(
        problem, rows, free, est.warm_nfev, floor, prior=prior, width_vectors=WIDTH_VECTORS)
    info = {"used": not inadequate, "birge_ratio": birge, "nfev": nfev,
            "forward_calls": problem.calls,
            "moved_m": float(np.max(np.linalg.norm(result.params[:, :3] - rows[:, :3], axis=1)))}
    history = [{"targets": len(rows), "cost": result.cost, "warm_start": True}]
    if inadequate:
        info["reason"] = _missed(floor)
        return None, info, Fitted(problem, Chosen(problem, result, free, cov), history)
    chosen = Chosen(problem, result, free, cov)
    if len(rows) == 1 and not floored:  # adequate: closed_or_plate keeps the plate (and
        # records why); no depth probe: a tracked frame stays a plate fit of a few evaluations.
        # (Within the cold fit's floor: that fit chose the plate over the closed shapes.)
        chosen = closed_or_plate(problem, result, free, est.final_nfev, cov, est.closed,
                                 probe_depth=False)
    return Fitted(problem, chosen, history), info, None


def _settled(problem, rows, free, nfev, floor, **options):
    """(result, cov, misses(...), evaluations): the warm LM fit from `rows` (model.fit with
    the warm settings and `options`), continued once (CONTINUE_NFEV times the budget) where it
    misses the data having spent its whole budget: stopped by the budget, not settled in a
    basin."""
    def warm_lm(start, budget):
        return fit(problem, start, free, budget, tau=WARM_TAU, atol=WARM_ATOL,
                   keep_jacobian=REUSE_JACOBIAN, best_gain=len(rows) <= BEST_GAIN_PLATES,
                   speculate=SPECULATE, **options)
    result = warm_lm(rows, nfev)
    cov = covariance(problem, result, free, reuse=REUSE_JACOBIAN)
    missed, spent = misses(problem, result, free, cov.info, floor), result.nfev
    if missed[0] and result.nfev >= nfev:
        result = warm_lm(result.params, CONTINUE_NFEV * nfev)
        cov = covariance(problem, result, free, reuse=REUSE_JACOBIAN)
        missed, spent = misses(problem, result, free, cov.info, floor), spent + result.nfev
    return result, cov, missed, spent


def _missed(floor) -> str:
    return "the warm fit misses the data (Birge ratio above its 99.9 % point" + (
        f" times the cold fit's {floor:.3g})" if floor and floor > 1.0 else ")")


def misses(problem, result, free, cov_info, floor=None) -> tuple[bool, float, bool]:
    """criteria.misfit's (misses, Birge ratio), the ratio counted in units of `floor` where the
    cold fit of these targets missed the data by that much, and whether the floor decided (the
    fit misses the noise's test but not the floor's): a frame's data that the model
    cannot explain to the noise (a learned background's residue, a person as a plate) sent
    every such frame to the cold fit, which landed on the same answer at the same misfit
    (docs/scenes/walk.yaml: 6 of 40 frames, warm 1.56-1.80 against cold 1.56-1.80, 3-12 s
    CPU each against 0.02 s)."""
    from .criteria import misfit
    inadequate, birge = misfit(problem, result, free, cov_info)
    if not inadequate or floor is None or floor <= 1.0:
        return inadequate, birge, False
    inadequate = misfit(problem, result, free, {"birge_ratio": birge / floor})[0]
    return inadequate, birge, not inadequate


def closed_warm_fit(est, problem, rows, free, shape, floor=None):
    """warm_fit's answer for rows of closed family `shape` (its name; a tracked person's
    cylinder, a box): only the final fit, in that family, from them. Without it a track whose
    target is closed was fitted cold every frame (a person's track: 10-45 s a frame on loaded
    cores, the whole selection and closed search), since its plate warm start misses a
    closed object's data. No size prior: the closed shapes model no shadows."""
    from ..forward.host_shapes import shape_problem
    from ..forward.likelihood import take_calls
    from .closed_search import closed_free
    closed = shape_problem(problem, SHAPES[shape])
    free_closed = closed_free(free)
    rows = np.clip(rows, closed.shape.LOWER, closed.shape.UPPER)
    result, cov, (inadequate, birge, _), nfev = _settled(closed, rows, free_closed,
                                                         est.warm_nfev, floor)
    take_calls(problem, closed)
    info = {"used": not inadequate, "birge_ratio": birge, "nfev": nfev,
            "forward_calls": problem.calls,
            "moved_m": float(np.max(np.linalg.norm(result.params[:, :3] - rows[:, :3], axis=1)))}
    fitted = Fitted(problem, Chosen(closed, result, free_closed, cov),
                    [{"targets": len(rows), "cost": result.cost, "warm_start": True}])
    if inadequate:
        info["reason"] = _missed(floor)
        return None, info, fitted
    return fitted, info, None


SIZE = [plate.WIDTH, plate.HEIGHT]


def size_prior(problem, rows, sizes):
    """(mean, sd) over the rows' parameters for model.fit's `prior`, or None: each plate the
    others partly hide at the start (> HIDDEN_SHARE of its paths blocked) with a known size
    (sizes: (size, sd), (K, 2) each; sd inf: unknown) has the mean's width and height set to
    that size, with that sd; the other rows and parameters are the start's, without a prior.
    Where a plate is partly hidden, a narrower plate over its visible part explains the data as
    well or better (crossing draw 15, frame 27: the true 0.52 m plate, half hidden, fitted at
    0.19 m and 0.15 m off, costing less than the truth even on noiseless data, so no better
    model fixes it); the size learnt while it was seen whole decides. A frame in which no plate
    is held is fitted as without a prior, bit for bit (one held plate moves the others' fit
    too: the fit is joint). The cold fit the estimator falls back to has no prior, and the
    warm/cold comparisons (estimator._warm_or_cold, tracking.warm.better) weigh data costs
    alone: where a narrow plate costs less, a fallback takes it."""
    if sizes is None or not problem.shadows or len(rows) < 2:
        return None
    from ..forward.shadow import hidden_shares
    size, size_sd = (np.asarray(v, float).reshape(len(rows), 2) for v in sizes)
    known = np.isfinite(size_sd).all(axis=1)
    mean, sd = np.array(rows, float), np.full(np.shape(rows), np.inf)
    mean[np.ix_(known, SIZE)] = size[known]
    # hidden at the known size (a plate already fitted small over its visible part is not)
    hidden = hidden_shares(mean, problem.obs.laser, problem.obs.spots)
    held = known & (hidden > HIDDEN_SHARE)
    mean[np.ix_(~held, SIZE)] = np.asarray(rows, float)[np.ix_(~held, SIZE)]
    sd[np.ix_(held, SIZE)] = size_sd[held]
    return (mean, sd) if held.any() else None


def _nearest_rows(centres, prior_centres) -> list[tuple[int, int]]:
    """(result row, prior row) pairs: the one-to-one matching with the least summed centre
    distance (SciPy's linear_sum_assignment, which the tracker's association imports anyway)."""
    from scipy.optimize import linear_sum_assignment
    gap = np.linalg.norm(centres[:, None] - prior_centres[None], axis=2)
    return [(int(k), int(j)) for k, j in zip(*linear_sum_assignment(gap))]


def checked_sizes(prior, k: int):
    """The Prior's (size, size_sd) for model.warm.size_prior, each (K, 2), or None."""
    if prior.size_sd is None:
        return None
    size, sd = (np.asarray(v, np.float64) if v is not None else None
                for v in (prior.size, prior.size_sd))
    require(size is not None and size.shape == (k, 2) and sd.shape == (k, 2)
            and bool(np.all(np.isfinite(size) & (size > 0))) and bool(np.all(sd > 0)),
            "prior", f"size and size_sd must both be (K={k}, 2) arrays of positive widths and "
            "heights and their sds (inf: unknown)", "pass Prior(rows, size, size_sd) with one "
            "row per target, or size_sd=None")
    return size, sd




def hidden_diagnostics(problem, result, prior=None) -> list[dict]:
    """Per target of the result, diagnostics: `hidden_share`, the share of its paths the other
    targets block (model.shadow.hidden_shares), at its fitted size or, where `prior` (the
    tracker's Prior; falsy: none) knows a larger one for the row nearest it, at that size (a
    plate fitted small over its lit part is not seen whole; a cold fit that replaced the warm
    one has its own order, hence the matching); 0.0 for one target, None where K >= 2 plates
    are fitted without shadows (the device Problem: unknown).
    `hidden_sd_m`: how far the hidden part could move the centre, share x half the plate's
    larger side at that size (m; a plate 78 % hidden is fitted over its lit part, its centre
    degenerate: crossing draw 8's frames 19-22 were 0.06-0.14 m off with fitted sds of 3-9
    mm); 0.0 or None as the share. It is not in the covariance, which stays the data's.
    `size_held`: the warm fit's size prior held its width and height (`size_prior`).
    Closed shapes: their front faces' (forward.shadow.plate_rows)."""
    from ..forward.shadow import plate_rows
    params = np.array(plate_rows(result.params))  # a copy: the prior's sizes go in below
    held = np.zeros(len(params), bool) if result.prior is None else \
        np.isfinite(np.asarray(result.prior[1])[:, [plate.WIDTH, plate.HEIGHT]]).any(axis=1)
    if len(params) < 2 or not problem.shadows:
        share = [0.0 if len(params) < 2 else None] * len(params)
        sd = share
    else:
        from ..forward.shadow import hidden_shares
        if prior and prior.size_sd is not None:
            prior_rows = np.asarray(prior.rows, float)  # plates or a closed family's rows
            rows = np.array(plate_rows(prior_rows.reshape(len(prior_rows), -1)))
            known = np.isfinite(np.asarray(prior.size_sd, float)).all(axis=1)
            size = np.asarray(prior.size, float)
            for k, j in _nearest_rows(params[:, :3], rows[:, :3]):
                if known[j]:
                    params[k, SIZE] = np.maximum(params[k, SIZE], size[j])
        obs = problem.obs
        share = [round(float(h), 4) for h in hidden_shares(params, obs.laser, obs.spots)]
        side = params[:, SIZE].max(axis=1)
        sd = [round(h * float(w) / 2, 4) for h, w in zip(share, side)]
    return [{HIDDEN_SHARE_KEY: h, HIDDEN_SD_KEY: d, "size_held": bool(b)}
            for h, d, b in zip(share, sd, held)]


def start_rows(est, start, shape=None) -> np.ndarray:
    """A warm start's rows (K, 6 plate or 7 closed-shape parameters: Prior.shape), checked
    against the estimator's settings."""
    rows = np.array(start, dtype=np.float64)
    rows = rows.reshape(1, -1) if rows.ndim == 1 else rows
    require(shape is None or shape in SHAPES, "start", f"shape {shape!r} is no model shape",
            f"use one of {sorted(SHAPES)} or None (plates)")
    n = SHAPES[shape or "plate"].N_PARAMS
    require(rows.ndim == 2 and rows.shape[1] == n and bool(np.all(np.isfinite(rows))),
            "start", f"must be finite rows (K, {n}) of the {shape or 'plate'}'s parameters; "
            f"got shape {rows.shape}", "pass the previous fit's details['params'] values, one "
            "row per target")
    require(est.targets == len(rows), "start", f"has {len(rows)} rows for targets="
            f"{est.targets!r}", "pass one row per target (warm starts need an integer "
            "number of targets)")
    require(est.closed is not True or shape not in (None, "plate"), "start", "warm starts of "
            "plates; closed=True always fits the closed shapes", "use closed='auto' or False, "
            "or start=None")
    return rows
