"""A track's body behind its plate: the depth a closed object's plate fits cannot see.

A plate fit of a closed object (a person, a box) lies on the surface that faces the wall
spots, and a warm fit is a plate where the last cold fit was one: a person's track followed his
front, his radius (0.15-0.3 m) short of his centre, while the frames whose cold fit found a
closed shape (model.policy.closed: a cylinder, box or ellipsoid, its centre the object's
own) measured the centre. Both kinds then pulled on one track. An object's depth does not
change from frame to frame, so each track learns it from the closed shapes paired with it
(`learn`: the median of their depths, the extent along their normal), and every fit paired
with a track that has learned one measures the centre behind its front (`centred`): a
plate's centre, or a closed shape's front face (a thin box fitted to a person's side is a
front too), moved half the learned depth behind it (a plate's horizontally away from the
wall spots, a closed shape's along its own normal), with the depth's spread added to the
measurement's variance along that way. A track that has been paired with fewer than
MIN_CLOSED closed shapes learns nothing and is moved by nothing: a thin plate's fits are
plates, and one closed fit of a plate with some light beside it says little; a closed fit
whose depth the fit held at its family's lower bound (0.04 m for a cylinder) counts as depth
0 (scenario clutter draw 72's plate was fitted three times as a 0.04 m deep cylinder).
"""
from __future__ import annotations

import math

import numpy as np

from . import kalman

MIN_CLOSED = 2  # closed fits paired with a track before its depth is used


def _fit(m):
    fit = getattr(m.source, "fit", None)
    return None if m.merged or fit is None else fit


def learn(track, m) -> None:
    """After pairing: remember the depth of a closed shape (not a plate) paired with track."""
    fit = _fit(m)
    if fit is None or fit.shape == "plate":
        return
    values = fit.values()
    if len(values) != 7:  # x y z width height depth yaw
        return
    params = getattr(fit, "parameters", ())
    sd = params[5].sd if len(params) == 7 else math.nan
    # a depth at its family's lower bound (0.04 m for a cylinder; within a millimetre, as
    # the solver leaves it) is a thin shape's: 0
    thin = len(params) == 7 and float(values[5]) <= params[5].lower + 1e-3
    track.depths.append((0.0 if thin else float(values[5]),
                         float(sd) if math.isfinite(sd) else 0.0))


def depth_of(track):
    """(depth, sd) the track has learned (m), or None (fewer than MIN_CLOSED closed fits):
    the median of the closed depths, its sd the larger of their spread (1.4826 MAD) and their
    fits' median sd."""
    depths = getattr(track, "depths", ())
    if len(depths) < MIN_CLOSED:
        return None
    d = np.array(depths, float)
    depth = float(np.median(d[:, 0]))
    spread = 1.4826 * float(np.median(np.abs(d[:, 0] - depth)))
    return depth, max(spread, float(np.median(d[:, 1])))


def centred(track, m, wall=None):
    """m as a measurement of track's centre: its front (a plate fit's centre; a closed fit's
    front face, half its own depth before its centre) moved half the learned depth behind:
    a closed fit's along its own normal, a plate's horizontally away from `wall` (the wall
    spots' centroid: the way the spots look at it; a narrow plate's yaw is poorly fitted;
    its own normal where wall is None), with (half the depth's sd)^2 added along that way;
    m itself where it is no model fit or the track has learned no depth."""
    fit, known = _fit(m), depth_of(track)
    normal = getattr(fit, "normal", None)
    if known is None or normal is None or not len(m.axes):
        return m
    position = np.asarray(m.position, float).reshape(3)
    n = _horizontal(np.asarray(normal, float).reshape(3))
    if n is None:
        return m
    if fit.shape == "plate":
        front = position
        away = -n if wall is None else _horizontal(position - np.asarray(wall, float))
    elif len(fit.values()) == 7:  # x y z width height depth yaw: a closed shape
        front, away = position + 0.5 * float(fit.values()[5]) * n, -n
    else:
        return m
    if away is None:
        return m
    depth, sd = known
    position = front + 0.5 * depth * away
    axes = m.axes
    u = away[axes]
    R = m.R + (0.5 * sd) ** 2 * np.outer(u, u)
    return kalman.Measurement(axes, position[axes], R, position, m.source, m.merged)


def _horizontal(v):
    """v's horizontal part as a unit vector (z is up), or None where it has none."""
    v = np.array(v, float).reshape(3)
    v[2] = 0.0
    norm = np.linalg.norm(v)
    return v / norm if norm > 0 else None


def offset(track, m) -> np.ndarray:
    """Where the measurement puts the track relative to its fit's plate (3,): what the warm
    start takes off the predicted centre to place the plate (zero: the plate is the centre)."""
    fit = _fit(m)
    if fit is None or fit.shape != "plate":
        return np.zeros(3)
    return np.asarray(m.position, float) - fit.values()[:3]
