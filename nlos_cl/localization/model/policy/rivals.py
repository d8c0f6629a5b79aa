"""Rival shapes: another closed family that fits the data nearly as well as the chosen one and
puts a target's centre elsewhere. The covariance is the chosen family's own: it says how well
the data pin that family's centre, not whether another family's centre (a person seen by
three spots as an ellipsoid, or as a cylinder 0.5 m away) explains them as well. Where the
family is that uncertain, the answer says so (`rival_note`).

Every closed family has the same parameters, so their costs compare directly: the difference
of -2 log L in units of the chosen fit's residual variance (criteria.depth_gain's `unit`) is
their BIC difference. A rival is a family within RIVAL_UNITS of the chosen one (Kass and
Raftery's "very strong" evidence starts at 10) whose centre lies farther than
RIVAL_DISTANCE_M from the chosen fit's. Measured on the scenario suite (96 draws, no option,
stop 69): said on 5 draws, all of them failures, 3 of which had no other warning (persons seen
by a triangle of 3 spots, 0.23-0.48 m off; rivals 5.4-6.6 units off, centres 0.18-0.51 m away);
none of the 68 answered within 0.15 m (docs/model-estimator.md, "Uncertainty").

The same line for the chosen family itself on photon counts (`centre_note`): its fit with the
centre held RIVAL_DISTANCE_M away (closed.centre_profile) within RIVAL_UNITS is said as well.
"""
from __future__ import annotations

import numpy as np

RIVAL_UNITS = 10.0
RIVAL_DISTANCE_M = 0.15  # the scenario suite's failure line
RIVALS_KEY = "rival_shapes"  # diagnostics: the chosen closed fit's rivals
# diagnostics: the chosen closed fit with its centre held RIVAL_DISTANCE_M away
# (closed.centre_profile), one target
CENTRE_RIVALS_KEY = "centre_rivals"
CENTRE_WARNING = ("the position of target {k} is poorly determined: with its centre "
                  "{distance:.2f} m away along the {direction}, the fit explains the data "
                  "nearly as well ({units:.1f} units of -2 log L worse; 10 would rule it out), "
                  "so the centre is uncertain by about that much")
RIVAL_WARNING = ("the shape of target {k} is ambiguous: a {shape} fits the data nearly as well "
                 "({units:.1f} units of -2 log L worse; 10 would rule it out) with its centre "
                 "{distance:.2f} m from the reported one, so the centre is uncertain by about "
                 "that much")


def rivals(fits, name: str, chosen, unit: float) -> list[dict]:
    """[{shape, units, distance_m: per target}] for each fit of `fits` ((name, result) pairs
    of closed families fitted to the same data and targets, in the same target order) of a
    family other than the chosen one (`name`, fit `chosen`) whose cost is within RIVAL_UNITS
    `unit`s of the chosen fit's and one of whose centres lies farther than RIVAL_DISTANCE_M
    from the chosen one's."""
    mine = np.asarray(chosen.params, float)[:, :3]
    out = []
    for other, result in fits:
        if other == name:
            continue
        units = (float(result.cost) - float(chosen.cost)) / unit
        apart = np.linalg.norm(np.asarray(result.params, float)[:, :3] - mine, axis=1)
        if units <= RIVAL_UNITS and apart.max() > RIVAL_DISTANCE_M:
            out.append({"shape": other, "units": units, "distance_m": apart.tolist()})
    return out


def rival_note(info, k: int, at: int) -> str | None:
    """RIVAL_WARNING for target k of the fit, reported as target at + 1, where a rival
    (info's RIVALS_KEY) puts its centre farther than RIVAL_DISTANCE_M (the farthest such
    rival named), else None."""
    far = [r for r in info.get(RIVALS_KEY, ()) if r["distance_m"][k] > RIVAL_DISTANCE_M]
    if not far:
        return centre_note(info, k, at)
    r = max(far, key=lambda r: r["distance_m"][k])
    return RIVAL_WARNING.format(k=at + 1, shape=r["shape"], units=max(r["units"], 0.0),
                                distance=r["distance_m"][k])


def centre_note(info, k: int, at: int) -> str | None:
    """CENTRE_WARNING where the one target's centre held RIVAL_DISTANCE_M away
    (CENTRE_RIVALS_KEY) costs at most RIVAL_UNITS more (the cheapest such point named),
    else None."""
    if k != 0:  # profiled for one target only
        return None
    near = [r for r in info.get(CENTRE_RIVALS_KEY, ()) if r["units"] <= RIVAL_UNITS]
    if not near:
        return None
    r = min(near, key=lambda r: r["units"])
    direction = ("line of sight from the laser spot" if r["direction"] == "line of sight"
                 else "least certain direction")
    return CENTRE_WARNING.format(k=at + 1, distance=abs(r["offset_m"]), direction=direction,
                                 units=max(r["units"], 0.0))
