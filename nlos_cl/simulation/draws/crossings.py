"""The geometry of a `crossings` draw (families draws the rest): two straight paths in x-y that
cross at a point X, each walked at constant speed over the sequence, timed so that the two
centres come no closer than a drawn distance (the targets pass X nearly together, one just
after the other, and never touch). Pure functions of their arguments; plain data out.

The timing: target i is at X at t_i = f_i T and moves at v_i. Their separation
v1 (t - t1) - v2 (t - t2) is smallest, over all t, at |t2 - t1| |v1 x v2| / |v1 - v2|; so the
offset t2 - t1 that gives a closest approach d is d |v1 - v2| / |v1 x v2|."""
from __future__ import annotations

import math

import numpy as np


def _u(rng, pair) -> float:
    return float(rng.uniform(*pair))


def _cross(a, b) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def _inside(point, region) -> bool:
    return (region["x"][0] <= point[0] <= region["x"][1]
            and region["y"][0] <= point[1] <= region["y"][1])


def crossing_paths(rng, fam: dict, region: dict, span_s: float, half_widths) -> dict | None:
    """Two crossing x-y paths ({paths: [[start, end], [start, end]], crossing_xy, turn_deg,
    fractions, offset_s, closest_m}), or None where this try leaves the region or the timing
    does not fit the sequence (the caller draws again)."""
    x = np.array([_u(rng, region["x"]), _u(rng, region["y"])])
    first = _u(rng, (0.0, 2 * math.pi))
    turn = math.radians(_u(rng, fam["turn_deg"])) * float(rng.choice([-1.0, 1.0]))
    ways = [np.array([math.cos(a), math.sin(a)]) for a in (first, first + turn)]
    lengths = [_u(rng, fam["length_m"]), _u(rng, fam["length_m"])]
    f1 = _u(rng, fam["crossing_fraction"])
    closest = float(sum(half_widths)) + _u(rng, fam["gap_m"])
    v1, v2 = (w * n / span_s for w, n in zip(ways, lengths))
    offset = closest * float(np.linalg.norm(v1 - v2)) / abs(_cross(v1, v2))
    offset *= float(rng.choice([-1.0, 1.0]))  # which of the two passes X first
    f2 = f1 + offset / span_s
    lo, hi = fam["crossing_fraction"]
    if not lo <= f2 <= hi:
        return None
    paths = []
    for way, length, f in zip(ways, lengths, (f1, f2)):
        start = x - way * length * f
        paths.append([start, start + way * length])
    if not all(_inside(p, region) for path in paths for p in path):
        return None  # a segment is convex: its ends inside keep all of it inside
    return {"paths": [[np.round(p, 6).tolist() for p in path] for path in paths],
            "crossing_xy": np.round(x, 6).tolist(), "turn_deg": round(math.degrees(turn), 3),
            "fractions": [round(f1, 6), round(f2, 6)], "offset_s": round(offset, 6),
            "closest_m": round(closest, 6)}


def segments_cross(a, b) -> bool:
    """Whether the x-y segments a = [p, q] and b = [r, s] intersect (strictly inside)."""
    p, q, r, s = (np.asarray(v, float)[:2] for v in (*a, *b))
    d1, d2 = _cross(q - p, r - p), _cross(q - p, s - p)
    d3, d4 = _cross(s - r, p - r), _cross(s - r, q - r)
    return d1 * d2 < 0 and d3 * d4 < 0


def closest_approach(paths, samples: int = 2001) -> float:
    """The smallest x-y distance between the two targets while they walk (sampled in time)."""
    t = np.linspace(0.0, 1.0, samples)[:, None]
    (a0, a1), (b0, b1) = (np.asarray(p, float)[:, :2] for p in paths)
    return float(np.linalg.norm((a0 + t * (a1 - a0)) - (b0 + t * (b1 - b0)), axis=1).min())
