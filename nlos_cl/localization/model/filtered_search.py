"""Photon counts searched twice: on the counts themselves, and on the same frame Gauss-filtered
(coarse in time: issue 23 item 3), whose answer the counts' likelihood then refits; the lower
Poisson cost wins.

Why: counts are not filtered, so the model's pulse is the laser's and the jitter alone (~1.3 cm
of path against ~6.6 cm filtered) and at thousands of photons a detector the Poisson deviance
is a narrow, many-basined landscape: every start candidate 15 cm off costs 30-50x the truth's,
their ranking says little, and the short fits settle in other basins. Counts draw 46 (a 0.95 x
0.42 m plate, 30 SPAD spots, 18,886 photons a detector): the counts search ended 45 degrees
off at cost 18,598 where a fit from the truth reaches 3,777, and the closed shapes, fitted
next, beat that plate with a box 0.26 m off. The filtered frame's landscape is the one the
Gaussian draws validated (one-target failures 4 %); its answer only has to land in the right
basin, which the counts' final fit then refines. For one target (targets=1), where the
estimator searches with starts.
"""
from __future__ import annotations

from . import data, select
from .fit import FitResult, fit


def smooth_observation(est, scored, obs):
    """The frame's Gauss observation (its filtered rows, as for Gaussian data) where `obs` is
    counts fitted for one target; else None."""
    if obs.mode != "poisson" or est.targets != 1:
        return None
    return data.observation(scored, "gauss", h_s=est.h_s, pulse_sigma_s=est.pulse_sigma_s,
                            jitter_s=est.jitter_s, frac=data.window_frac(est.targets))


def better_from_filtered(est, problem, rough: FitResult, smooth_obs, argmax_position, free,
                         held) -> FitResult:
    """rough (the counts search's answer on `problem`), or the counts fit from the search on
    `smooth_obs` (the same detectors' filtered frame: model.data's Gauss observation) where
    that costs less."""
    smooth = est.problem(smooth_obs, problem.backend)
    found, _ = select.fit_targets(smooth, est, argmax_position, free, held)
    problem.calls += smooth.calls  # the counts' problem counts every forward call made for it
    problem.model_s += smooth.model_s
    again = fit(problem, found.params, free, est.final_nfev, atol=select.FINAL_ATOL)
    return again if again.cost < rough.cost else rough


def searched(est, problem, argmax_position, free, held, smooth=None):
    """(result, history): select.fit_targets on `problem`, and with `smooth` (the same
    detectors' filtered frame, or None) `better_from_filtered` after it."""
    result, history = select.fit_targets(problem, est, argmax_position, free, held)
    if smooth is not None:
        result = better_from_filtered(est, problem, result, smooth, argmax_position, free, held)
    return result, history
