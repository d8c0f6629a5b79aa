"""Many detectors: what the estimator decides on spread subsets of them, and what it fits on
all of them.

- More than SEARCH_DETECTORS (64): the starts and short fits run on 64 spread detectors
  (`cold_fit`), the final plate fit on all, from the subset's answer, in at most
  FINISH_NFEV evaluations (core/tuning.py).
- More than CHOICE_DETECTORS (8), and a plate that misses the data or that a box behind it
  would beat (the depth probe on every detector): the choice of plate or closed shape
  (model.closed.closed_or_plate: the pooled search of three families, ~15 LM fits) is made on 8 spread
  detectors (`_choice`), and only the chosen closed shape is refitted on all
  (`plate_or_closed`), unless the sanity check will reject it (`doomed`): closed fits cost
  their detectors.
- Where the search subset's plate already misses the data, the choice is made before the
  final fit, and a closed shape that sanity.doubt will reject there (`doomed`: its misfit
  above MISFIT_BIRGE and its depth unseen or the signal unexplained) ends the fit on the
  subset: the answer is the paper's argmax with the reason, and nothing is fitted on every
  detector. On CC-SOCR's 4,096 points as one laser the ellipsoid refitted on all of them was
  rejected for the same reasons as on the subset (residual 374 times the noise's, depth sd
  0.30 m).
On 8 spread detectors (core/tuning.py's CHOICE_DETECTORS) that capture takes 7.8 s, the same
depth (0.955 m) as on all (history: docs/model-estimator.md, "How the rules got here").
"""
from __future__ import annotations

import numpy as np

from ....core import progress
from ....core.geometry import farthest_points
from ....core.tuning import (
    CHOICE_DETECTORS,
    FINISH_NFEV,
    MAX_EXTENT_M,
    SEARCH_DETECTORS,
)
from ..forward.likelihood import take_calls
from ..shapes.shape import name_of
from ..solve.covariance import covariance
from ..solve.fit import fit, shape_of
from ..solve.records import Chosen, SubsetChoice
from .closed import box_behind, closed_or_plate
from .criteria import misfit
from .sanity import closed_centre_guessed, fit_checks


def spread_rows(obs, count=SEARCH_DETECTORS) -> np.ndarray:
    """`count` detectors spread over the wall (an index stride can pick one line of a
    raster), by their spots and lasers."""
    return farthest_points(np.hstack([obs.spots, np.broadcast_to(obs.laser, obs.spots.shape)]),
                           count)


def _choice(est, problem, plate_result, free, tried=False, smooth=None):
    """A SubsetChoice (the subset's problem, closed_or_plate on it): the plate refitted on CHOICE_DETECTORS
    spread detectors from `plate_result`, and the choice made there (tried: the closed shapes
    fitted there whatever the subset's plate does: every detector's probe asked for them;
    smooth: None, or (counts) the frame's Gauss observation: closed.closed_fits)."""
    rows = spread_rows(problem.obs, CHOICE_DETECTORS)
    few = est.problem(problem.obs.detectors(rows), problem.backend)
    plate_there = fit(few, plate_result.params, free, est.final_nfev)
    answer = closed_or_plate(few, plate_there, free, est.final_nfev,
                             covariance(few, plate_there, free), est.closed, tried=tried,
                             smooth=smoothed(est, smooth, problem.backend, rows),
                             sanity=est.sanity)
    take_calls(problem, few)
    return SubsetChoice(few, answer)


def cold_fit(est, problem, argmax_position, free, held, smooth=None):
    """fit_targets on the spread subset, then, for one target whose plate misses the subset's
    data (closed='auto'), the plate-or-closed choice there; a `doomed` closed shape ends the
    fit (sanity on). Else the final fit on every detector, keeping its last Jacobian for the
    covariance (model.covariance's `reuse`).
    Returns (result on all detectors or None, history, choice): choice None (not made),
    or a SubsetChoice. smooth: None, or (counts) the
    frame's Gauss observation, searched instead, on the same subset (model.filtered_search)."""
    from .filtered_search import searched
    rows = spread_rows(problem.obs)
    search = est.problem(problem.obs.detectors(rows), problem.backend)
    rough, history = searched(est, search, argmax_position, free, held,
                              None if smooth is None else smooth.detectors(rows))
    choice = None
    if len(rough.params) == 1 and est.closed == "auto":
        cov = covariance(search, rough, free)
        if misfit(search, rough, free, cov.info)[0]:
            choice = _choice(est, problem, rough, free, smooth=smooth)
    take_calls(problem, search)
    if choice is not None and _ended(est, choice) is not None:
        return None, history, choice
    progress.stage(f"model fit: the final fit on all {len(problem.obs.spots):,} histograms")
    result = fit(problem, rough.params, free, min(est.final_nfev, FINISH_NFEV),
                 keep_jacobian=True)
    return result, history, choice


def doomed(chosen, result, free, cov) -> bool:
    """Whether sanity.doubt will reject this fit: larger than any target (MAX_EXTENT_M), or
    misfit with its depth unseen or the signal unexplained (the fields model.estimator
    reports: sanity.fit_checks). LCT's "SU" scan (counts in groups of 3 bins): a cylinder
    chosen on 8 spots at its 3 m height bound was refitted on all 4,096 (786 of 1,053 s,
    under load) and then rejected for its size."""
    if len(result.params) == 1 and float(np.max(shape_of(chosen).extent(
            result.params[0]))) > MAX_EXTENT_M:
        return True
    return closed_centre_guessed(name_of(chosen.shape), fit_checks(chosen, result, free, *cov))


def _ended(est, choice):
    """The subset's answer where the choice made there ends the fit (a `doomed` closed
    shape, the sanity check on), with how many detectors it was fitted on; else None."""
    few, answer = choice
    if not est.sanity or answer.problem is few or not doomed(*answer):
        return None
    answer.cov.info.update(subset_detectors=len(few.obs.spots))
    return answer


def smoothed(est, smooth, backend, rows=None):
    """The problem of the Gauss observation `smooth` (on its detectors `rows`), or None."""
    if smooth is None:
        return None
    return est.problem(smooth if rows is None else smooth.detectors(rows), backend)


def plate_or_closed(est, problem, result, free, cov, choice=None, smooth=None):
    """closed_or_plate on the fitted plate of estimator `est` (model.estimator's _cold). With
    more than CHOICE_DETECTORS detectors and closed shapes to fit (a plate that misses the
    data, or one a box behind would beat: closed.box_behind on every detector), the choice
    is made on a spread subset (`choice`, where `cold_fit` made it already) and only the
    chosen closed shape is refitted on all of them, unless it is `doomed` (sanity on): then
    the subset's fit is the answer the check replaces. smooth: None, or (counts) the frame's
    Gauss observation, where closed shapes are also sought (closed.closed_fits)."""
    obs = problem.obs
    if len(obs.spots) <= CHOICE_DETECTORS or est.closed != "auto":  # few spots, or no choice
        return closed_or_plate(problem, result, free, est.final_nfev, cov, est.closed,
                               smooth=smoothed(est, smooth, problem.backend),
                               sanity=est.sanity, beyond=True)
    if choice is None:
        inadequate, birge = misfit(problem, result, free, cov.info)
        if not inadequate:
            # a plate that fits: closed shapes only where the depth probe on every detector
            # says a box behind it does better (as closed_or_plate), and then they too are
            # chosen on the subset (a 48-spot SPAD patch of counts spent 371 s fitting them
            # on all 48)
            cov.info.update(plate_birge_ratio=birge, closed_tried=False)
            if not box_behind(problem, result, cov):
                return Chosen(problem, result, free, cov)
        choice = _choice(est, problem, result, free, tried=not inadequate, smooth=smooth)
    search, (chosen, there, free_there, (_, why)) = choice
    if chosen is search:  # the plate: its fit on every detector stands, with the choice's notes
        cov.info.update({k: v for k, v in why.items() if k not in cov.info})
        return Chosen(problem, result, free, cov)
    ended = _ended(est, choice)
    if ended is not None:
        return ended
    from ..forward.host_shapes import shape_problem
    full = shape_problem(problem, shape_of(chosen))
    # above SEARCH_DETECTORS the subset's fit is finished, as cold_fit finishes the plate's:
    # LCT's 4,096 x 683 counts spent ~100 s in 30 evaluations of a closed shape here
    nfev = est.final_nfev if len(obs.spots) <= SEARCH_DETECTORS else min(est.final_nfev,
                                                                         FINISH_NFEV)
    refit = fit(full, there.params, free_there, nfev)
    cov_full = covariance(full, refit, free_there)
    cov_full.info.update({k: v for k, v in why.items() if k not in cov_full.info})
    return Chosen(full, refit, free_there, cov_full)


def one_closed_instead(est, problem, argmax_position, free, held, several, smooth=None):
    """targets='auto' fitted a plate more where one plate missed the data; one closed target
    may explain it with fewer parameters (a box's lit side taken up by a second plate). The
    one-target fit and its plate_or_closed choice: kept where the shape chosen is closed and
    explains the data (misfit), else `several` (a Chosen) stands. Costs a one-target fit, only
    where 'auto' found several targets."""
    import copy
    one = copy.copy(est)
    one.targets = 1
    result, _, choice = one._fit(problem, argmax_position, free, held, smooth)
    if result is None:  # decided on a subset (cold_fit): its choice is a Chosen already
        single = choice.chosen
    else:
        cov = covariance(problem, result, free, reuse=result.jacobian is not None)
        single = plate_or_closed(one, problem, result, free, cov, choice, smooth)
    if not shape_of(single.problem).CLOSED or misfit(single.problem, single.result,
                                                     single.free, single.cov.info)[0]:
        return several
    return single
