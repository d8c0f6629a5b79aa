"""The target's reflectance lobe chosen by evidence (issue 57, item 1): glossy targets.

A glossy target (a GGX lobe over a small diffuse base: painted metal, plastic, a car's side)
sends each detector spot a share of its light that the Lambertian model cannot give with one
amplitude, so the Lambertian fit moves the target to make the amplitudes fit: the draws'
mismatch family's glossy sub-family failed 55 % (> 0.15 m, median 0.18 m) where the fit told
the true lobe found 9 of 10 of those failures within 0.002-0.07 m (stop 72).

Where the Lambertian fit of one target misses the data (its Birge ratio above the noise's
99.9 % point: `criteria.misfit`) or leaves signal unexplained (the detection's test on its
residual, `sanity.leftover_note`), Gaussian data only (photon counts: the counts family's
misfits are not glossy; the search there changed no answer of 400 and cost up to 39x a
locate, 0.9 -> 35.6 s; stop 72):
1. the cold fit of one target runs again with a middle lobe (`START`), which finds the basin
   and the shape family (a grid of six lobes, each a cold fit, cost 6x the time and its
   coarse lobes sent closed targets to the wrong family: a cylinder fitted as a capsule
   0.33 m off);
2. the lobe (roughness, diffuse share) is refined by a pattern search of warm fits of that
   shape from the best rows so far (`refined`: steps halved where no neighbour lowers the
   cost, at most MAX_WARM fits; ended after one round where the START fit explains less than
   the Lambertian one and no step helps), on LOBE_DETECTORS spread detectors of a bigger
   capture, its lobe then finished on all (`_search`);
3. the lobe is kept where its BIC gain over the Lambertian fit, counting the lobe's two
   parameters, is positive (`criteria.depth_gain`, in the misfit's units as the closed
   shapes' choice) and it explains EXCESS_EXPLAINED of the Lambertian misfit's excess;
4. and where it still pays its two parameters against the Lambertian model refitted warm
   from the lobe fit's own answer (`_flat_there`): the START cold fit and the pattern's warm
   fits are a second search, and where the Lambertian cold fit had missed the basin (a
   narrow box 0.67 m deep seen corner-on, fitted as a cylinder 0.31 m off), the lobe fit
   found it and was reported glossy at the search's broadest lobe; the Lambertian fit from
   there explains the data as well (Birge ratio 0.94 against 0.96), and it is the answer,
   Lambertian. (Not from the START fit's answer, before the pattern search: a person on 3
   spots, scenario draw 3, came back 0.23 m off and unwarned from there, 0.03 m from the
   refined lobe's answer.)
Targets the Lambertian fit explains are not touched: their answer, and its time, are what they
were. The chosen lobe is reported in the fit's diagnostics (`reflectance`). A reflectance given
by the caller (ModelEstimator(reflectance=), a Lambertian BRDF included) is used as given;
warm-started fits (a tracker's frames) keep the Lambertian model."""
from __future__ import annotations

import copy
import math
import warnings

import numpy as np

from ....physics.reflectance import GGX
from ..shapes.shape import name_of
from .criteria import depth_gain, misfit
from .sanity import leftover_note

START = (0.22, 0.15)  # (roughness a, diffuse share of the albedo) of the cold fit
ROUGHNESS = (0.05, 0.8)  # the search's bounds; a >= 0.5 is nearly Lambertian already
DIFFUSE = (0.0, 0.7)
STEPS = (math.log(1.6), 0.15)  # the pattern's first steps: log a, diffuse share
MAX_WARM = 14
MIN_STEP = 0.2  # of the first steps: below, the search ends
LOBE_PARAMETERS = 2  # roughness and diffuse share: the BIC's count
# Above this many detectors the lobe is refined on as many spread ones (a SPAD patch's
# neighbours see nearly the same angles) and only its best fit is finished on all. The START
# fit stays on all: cold on 16 of a glossy box's 32 spots it chose an ellipsoid 0.9 m off
# (mismatch draw 138; on all, the box within 0.003 m).
LOBE_DETECTORS = 16
# ... and only where the lobe explains most of what the Lambertian fit missed: of the
# Lambertian Birge ratio's excess over 1 (the noise's), at least EXCESS_EXPLAINED. The BIC
# alone, in misfit units, took a lobe for light the model lacks (stop 72, mismatch draws,
# Lambertian -> lobe Birge ratio, the share of the excess, the error): background 79 10.6 ->
# 6.7 (40 %, 0.03 -> 0.48 m), 169 8.1 -> 2.9 (73 %, 0.12 -> 0.33 m), a glossy cylinder 43
# 2.4 -> 1.9 (38 %, 0.04 -> 0.13 m); glossy targets the lobe finds: 133 19.7 -> 4.7 (80 %),
# 183 35.7 -> 4.1 (91 %), 13 195 -> 3.1 (99 %), a box with peak noise 97 4.8 -> 0.7 (all).
# A ratio of Birge ratios (4x) instead lost the glossy SPAD patches, whose Lambertian misfit
# is small against their many bins (158: 1.8). Lost with it: Lambertian cylinder closed 26,
# 16 -> 6.5 (63 %; 0.24 -> 0.04 m with the lobe).
EXCESS_EXPLAINED = 0.75


def lobe_of(roughness: float, diffuse_share: float) -> GGX:
    """A GGX lobe of unit albedo (the amplitude absorbs the scale)."""
    return GGX(specular=1.0 - diffuse_share, roughness=roughness, diffuse=diffuse_share)


def unexplained(est, fitted) -> bool:
    """Does the fit of one target leave signal the Lambertian model does not explain?"""
    problem, result, free, cov = fitted.chosen
    if len(result.params) != 1 or problem.obs.mode != "gauss":
        return False
    return misfit(problem, result, free, cov.info)[0] or \
        leftover_note(problem, result, est.targets) is not None


def _birge(fitted) -> float:
    problem, result, free, cov = fitted.chosen
    return misfit(problem, result, free, cov.info)[1]


def _explained(before: float, after: float) -> float:
    """The share of the Birge ratio's excess over 1 (the noise's) that `after` removes."""
    return (before - after) / max(before - 1.0, 1e-12)


def _with(est, lobe):
    """est fitting one target with `lobe` (None: Lambertian): the search follows a one-target
    fit, and under targets='auto' the middle lobe's cold fit tried more plates (a 64-spot
    glossy patch's second pass, the locate's search for more targets: 232 s, and its answer,
    two plates, was dropped)."""
    trial = copy.copy(est)
    trial.reflectance, trial.targets = None if lobe is None else lobe_of(*lobe), 1
    return trial


def _quiet(run):
    """run()'s answer and the warnings it gave, not said (said again for the answer kept)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = run()
    return out, caught


def _warm(est, obs, rows, shape, where):
    """A warm fit of `rows` (a closed family `shape`, or None: plates) with est's reflectance:
    its Fitted, whether or not it explains the data (policy.warm.warm_fit)."""
    from .warm import warm_fit
    free, held, backend = where
    fitted, _, missed = warm_fit(est, obs, rows, free, held, backend, shape=shape)
    return fitted or missed


def refined(est, fitted, lobe, where, worse=False):
    """(fitted, lobe, warnings, (fits, calls, model seconds)): the pattern search over (log
    roughness, diffuse share) from `lobe`, each point a warm fit of the best fit's shape from
    its rows (`where`: the fit's free mask, held axis and backend); the best fit found, its
    lobe, and the warm fits' count and work. worse: `fitted` explains the data less than the
    Lambertian fit did; then a first round of steps that finds no better lobe ends the search
    (stop 73, the glossy and background mismatch draws' 73 searches: 19 started below 0 and
    moved no lobe, all rejected; the two kept that started below 0, 3 and 103, moved in the
    first round)."""
    best, cost, said = fitted, fitted.chosen.result.cost, []
    step, fits, calls, model_s = np.array(STEPS), 0, 0, 0.0
    while fits < MAX_WARM and step[1] >= MIN_STEP * STEPS[1]:
        moved = False
        for axis, sign in ((0, 1), (0, -1), (1, 1), (1, -1)):
            at = np.array([math.log(lobe[0]), lobe[1]])
            at[axis] += sign * step[axis]
            new = (float(np.clip(math.exp(at[0]), *ROUGHNESS)), float(np.clip(at[1], *DIFFUSE)))
            if new == tuple(lobe) or fits >= MAX_WARM:
                continue
            trial, caught = _moved(est, fitted.problem.obs, best, new, where, est.warm_nfev)
            fits, calls = fits + 1, calls + trial.problem.calls
            model_s += trial.problem.model_s
            if len(trial.chosen.result.params) == 1 and trial.chosen.result.cost < cost:
                best, cost, lobe, said, moved = trial, trial.chosen.result.cost, new, caught, True
                break
        if not moved and worse and best is fitted:
            break
        if not moved:
            step = step / 2
    return best, lobe, said, (fits, calls, model_s)


def _searched_on(obs):
    """The detectors the lobe is refined on: all, or LOBE_DETECTORS spread ones."""
    if len(obs.spots) <= LOBE_DETECTORS:
        return obs
    from .subset import spread_rows
    return obs.detectors(spread_rows(obs, LOBE_DETECTORS))


def _moved(est, obs, fitted, lobe, where, nfev):
    """(Fitted, warnings): `fitted`'s answer refitted warm with `lobe` on `obs`, its shape
    kept, in `nfev` evaluations (the pattern's steps: a warm fit's; onto other detectors: a
    cold fit's final budget)."""
    problem, result = fitted.chosen.problem, fitted.chosen.result
    shape = name_of(problem.shape)
    trial = _with(est, lobe)
    trial.warm_nfev = nfev
    return _quiet(lambda: _warm(trial, obs, result.params,
                                None if shape == "plate" else shape, where))


def _search(est, start, said, where, worse):
    """(best fit on every detector, its lobe, its warnings, (warm fits, calls, model s)): the
    pattern search from the START fit `start` (said: its warnings), on every detector or, above
    LOBE_DETECTORS, on a spread subset with the lobe found finished on all."""
    obs = start.problem.obs
    few = _searched_on(obs)
    if few is obs:
        best, lobe, later, work = refined(est, start, START, where, worse)
        return best, lobe, later or said, work
    on_few = _moved(est, few, start, START, where, est.final_nfev)[0]
    best, lobe, later, (fits, calls, model_s) = refined(est, on_few, START, where, worse)
    calls, model_s = calls + on_few.problem.calls, model_s + on_few.problem.model_s
    if lobe == START:
        return start, START, said, (fits, calls, model_s)
    finished, later = _moved(est, obs, best, lobe, where, est.final_nfev)
    calls, model_s = calls + finished.problem.calls, model_s + finished.problem.model_s
    if finished.chosen.result.cost >= start.chosen.result.cost:
        # the subset's lobe fits every detector worse than START did (mismatch draws 39, 44,
        # 79, 129: refined on 16 of 24-42 spots): the START fit stands
        return start, START, said, (fits, calls, model_s)
    return finished, lobe, later, (fits, calls, model_s)


def with_lobe(est, fitted, cold, where):
    """(fitted, report): the Lambertian cold fit `fitted`, or the fit with the GGX lobe the
    evidence prefers; report None (not tried), or what the choice found (the diagnostics'
    `reflectance`). cold(estimator): the cold fit with that estimator's reflectance; where:
    (free mask, held axis, backend) of the warm fits that refine the lobe. Above
    LOBE_DETECTORS detectors the refinement runs on a spread subset (`_search`); the choice
    is made on all."""
    if not est.lobe_search or not unexplained(est, fitted):
        return fitted, None
    base = fitted.chosen.result.cost
    start, said = _quiet(lambda: cold(_with(est, START)))
    calls = fitted.problem.calls + start.problem.calls
    model_s = fitted.problem.model_s + start.problem.model_s
    fitted.problem.calls, fitted.problem.model_s = calls, model_s  # the timings count all
    report = {"model": "lambertian"}
    if len(start.chosen.result.params) != 1:
        return fitted, report
    before = _birge(fitted)
    start_explained = _explained(before, _birge(start))
    best, lobe, said, (fits, more, more_s) = _search(est, start, said, where,
                                                     worse=start_explained < 0)
    fitted.problem.calls, fitted.problem.model_s = calls + more, model_s + more_s
    problem, result, free, cov = best.chosen
    gain, _ = depth_gain(problem.obs, base, problem, result, free, cov.info, LOBE_PARAMETERS)
    after = _birge(best)
    explained = _explained(before, after)
    report.update(bic_gain=round(float(gain), 2), birge_ratios=[round(before, 3),
                  round(after, 3)], excess_explained=round(float(explained), 3),
                  start_explained=round(float(start_explained), 3), warm_fits=fits)
    if len(problem.obs.spots) > LOBE_DETECTORS:
        report.update(refined_on=LOBE_DETECTORS)
    if gain <= 0 or explained < EXCESS_EXPLAINED:
        return fitted, report
    flat, flat_said, flat_gain = _flat_there(est, best, where)
    report.update(gain_over_lambertian_there=round(float(flat_gain), 2))
    calls = fitted.problem.calls + flat.problem.calls
    model_s = fitted.problem.model_s + flat.problem.model_s
    if flat_gain <= 0:  # a basin, not a lobe: the Lambertian fit there is the answer
        best, lobe, said, report["model"] = flat, None, flat_said, "lambertian"
    best.problem.calls, best.problem.model_s = calls, model_s
    _say(said)
    if lobe is not None:
        report.update(model="ggx", roughness=round(lobe[0], 4), diffuse_share=round(lobe[1], 4))
    return best, report


def _say(caught) -> None:
    for w in caught:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def _flat_there(est, best, where):
    """(Lambertian fit, its warnings, the lobe's BIC gain over it): `best`'s answer refitted
    warm with the Lambertian model on every detector, its shape kept (a cold fit's final
    budget); the lobe's two parameters counted as in `with_lobe`."""
    problem, result, free, cov = best.chosen
    flat, said = _moved(est, problem.obs, best, None, where, est.final_nfev)
    gain, _ = depth_gain(problem.obs, flat.chosen.result.cost, problem, result, free, cov.info,
                         LOBE_PARAMETERS)
    return flat, said, gain
