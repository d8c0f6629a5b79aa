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
1. the cold fit runs again with a middle lobe (`START`), which finds the basin and the shape
   family (a grid of six lobes, each a cold fit, cost 6x the time and its coarse lobes sent
   closed targets to the wrong family: a cylinder fitted as a capsule 0.33 m off);
2. the lobe (roughness, diffuse share) is refined by a pattern search of warm fits of that
   shape from the best rows so far (`refined`: steps halved where no neighbour lowers the
   cost, at most MAX_WARM fits);
3. the lobe is kept where its BIC gain over the Lambertian fit, counting the lobe's two
   parameters, is positive (`criteria.depth_gain`, in the misfit's units as the closed
   shapes' choice) and it explains EXCESS_EXPLAINED of the Lambertian misfit's excess.
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


def _with(est, lobe):
    trial = copy.copy(est)
    trial.reflectance = lobe_of(*lobe)
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


def refined(est, fitted, lobe, where):
    """(fitted, lobe, warnings, (fits, calls, model seconds)): the pattern search over (log
    roughness, diffuse share) from `lobe`, each point a warm fit of the best fit's shape from
    its rows (`where`: the fit's free mask, held axis and backend); the best fit found, its
    lobe, and the warm fits' count and work."""
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
            problem, result = best.chosen.problem, best.chosen.result
            shape = name_of(problem.shape)
            trial, caught = _quiet(lambda: _warm(_with(est, new), fitted.problem.obs,
                                                 result.params,
                                                 None if shape == "plate" else shape, where))
            fits, calls = fits + 1, calls + trial.problem.calls
            model_s += trial.problem.model_s
            if len(trial.chosen.result.params) == 1 and trial.chosen.result.cost < cost:
                best, cost, lobe, said, moved = trial, trial.chosen.result.cost, new, caught, True
                break
        if not moved:
            step = step / 2
    return best, lobe, said, (fits, calls, model_s)


def with_lobe(est, fitted, cold, where):
    """(fitted, report): the Lambertian cold fit `fitted`, or the fit with the GGX lobe the
    evidence prefers; report None (not tried), or what the choice found (the diagnostics'
    `reflectance`). cold(estimator): the cold fit with that estimator's reflectance; where:
    (free mask, held axis, backend) of the warm fits that refine the lobe."""
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
    best, lobe, later, (fits, more, more_s) = refined(est, start, START, where)
    said = later or said
    fitted.problem.calls, fitted.problem.model_s = calls + more, model_s + more_s
    problem, result, free, cov = best.chosen
    gain, _ = depth_gain(problem.obs, base, problem, result, free, cov.info, LOBE_PARAMETERS)
    before, after = _birge(fitted), _birge(best)
    explained = (before - after) / max(before - 1.0, 1e-12)
    report.update(bic_gain=round(float(gain), 2), birge_ratios=[round(before, 3),
                  round(after, 3)], excess_explained=round(float(explained), 3), warm_fits=fits)
    if gain <= 0 or explained < EXCESS_EXPLAINED:
        return fitted, report
    for w in said:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    best.problem.calls, best.problem.model_s = fitted.problem.calls, fitted.problem.model_s
    report.update(model="ggx", roughness=round(lobe[0], 4), diffuse_share=round(lobe[1], 4))
    return best, report
