"""Crossing targets (issue 22's crossings draws), on host-made fits (no simulation): where the
warm-started fit lands outside every track's gate, the tracker fits the frame cold and keeps
whichever of the two fits explains the frame better (nlos_cl.tracking.warm.better); a cold
fit in a worse basin no longer replaces a good warm one (draws 7, 16, 20: B ~ 1 warm, 100 cold)."""
import numpy as np

from nlos_cl.localization.estimate import LocatedTarget
from nlos_cl.localization.fit_result import ModelFit
from nlos_cl.tracking import kalman, warm


def _located(cost):
    """(Location, measurements) of a two-plate fit whose whole-frame cost is `cost`."""
    fit = ModelFit("plate", "upright plate", (), 1.0, np.zeros(3), "gauss", cost, 976, 1.0, False)
    targets = [LocatedTarget(np.array(p, float), np.diag([1e-5, 1e-5, np.inf]), None, fit=fit)
               for p in ([3.0, 2.0, 0.0], [3.5, 2.4, 0.0])]
    return None, [kalman.measurement(t, 2, fallback_sigma_m=0.05, min_sigma_m=0.002)
                  for t in targets]


def test_the_fit_with_the_lower_cost_is_kept():
    warm_fit, cold_fit = _located(480.0), _located(52_000.0)
    assert warm.better(warm_fit, cold_fit) is warm_fit
    assert warm.better(cold_fit, warm_fit) is warm_fit  # whichever was fitted first
    better_cold = _located(470.0)
    assert warm.better(warm_fit, better_cold) is better_cold


def test_a_fit_without_a_cost_loses():
    cold_fit = _located(52_000.0)
    assert warm.better((None, []), cold_fit) is cold_fit  # the warm frame found nothing
    assert warm.better(cold_fit, (None, [])) is cold_fit
