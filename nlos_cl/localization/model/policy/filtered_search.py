"""Photon counts searched on their Gauss-filtered frame (coarse in time): the
starts, short fits and K of `select.fit_targets` run on the filtered samples, as for Gaussian
data, and the counts' Poisson likelihood then refits that answer (the final fit).

Why: counts are not filtered, so the model's pulse is the laser's and the jitter alone (~1.3 cm
of path against ~6.6 cm filtered) and at thousands of photons a detector the Poisson deviance
is a narrow, many-basined landscape: every start candidate 15 cm off costs 30-50x the truth's,
their ranking says little, and the short fits settle in other basins. Counts draw 46 (a 0.95 x
0.42 m plate, 30 SPAD spots, 18,886 photons a detector): the counts search ended 45 degrees
off at cost 18,598 where a fit from the truth reaches 3,777, and the closed shapes, fitted
next, beat that plate with a cylinder 0.5 m off. The filtered frame's landscape is the one the
Gaussian draws validated; its answer only has to land in the right basin.

On counts draws 0-79 the filtered search alone fails 22 (> 0.15 m), p90 0.373 m, where the
counts search alone failed 27, in the counts search's time. For one target (targets=1).
"""
from __future__ import annotations

from ....core import progress
from ..forward import data
from ..forward.likelihood import take_calls
from ..solve.fit import fit
from . import select


def smooth_observation(est, scored, obs):
    """The frame's Gauss observation (its filtered rows, as for Gaussian data) where `obs` is
    counts fitted for one target; else None."""
    if obs.mode != "poisson" or est.targets != 1:
        return None
    return data.observation(scored, "gauss", h_s=est.window_s(scored), pulse_sigma_s=est.pulse_sigma_s,
                            jitter_s=est.jitter_s, frac=data.window_frac(est.targets))


def searched(est, problem, argmax_position, free, held, smooth=None):
    """(result on `problem`, history): select.fit_targets on `problem`; with `smooth` (the same
    detectors' filtered frame) fit_targets there and `problem`'s final fit from its answer.
    The history (ModelFit.targets_tried) then reports each entry's cost on the filtered frame
    as `filtered_cost` and the counts' cost of the answer as its `cost`, so that the costs a
    fit reports are all of its own likelihood."""
    progress.stage(f"model fit: starts and short fits ({len(problem.obs.spots):,} histograms)")
    if smooth is None:
        return select.fit_targets(problem, est, argmax_position, free, held)
    filtered = est.problem(smooth, problem.backend)
    found, history = select.fit_targets(filtered, est, argmax_position, free, held)
    take_calls(problem, filtered)
    result = fit(problem, found.params, free, est.final_nfev, atol=select.FINAL_ATOL)
    k = len(result.params)
    return result, [{**h, "searched_on": "filtered frame", "filtered_cost": h["cost"],
                     "cost": result.cost if h["targets"] == k else None} for h in history]
