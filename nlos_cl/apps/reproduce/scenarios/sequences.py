"""The clutter family's sequences: movers (plates or people) walking straight past static
furniture (boxes, cabinets) over the frames, as `nlos-cl simulate SCENE --frames N` writes them
and `nlos-cl track` reads them. A mover's "path" is [start, end], walked at constant speed from
frame 0 to the last; its "centre" is where it starts."""
from __future__ import annotations

import math

import numpy as np

from . import objects as dr


def at(o: dict, t_s: float, span_s: float) -> np.ndarray:
    """Where object `o` is at time t_s (a mover on its path; furniture where it stands)."""
    if not o.get("path"):
        return np.asarray(o["centre"], float)
    a, b = (np.asarray(p, float) for p in o["path"])
    return a + (b - a) * min(max(t_s / span_s, 0.0), 1.0) if span_s > 0 else a


def _in_region(point, cfg) -> bool:
    reg = cfg["region"]
    return reg["x"][0] <= point[0] <= reg["x"][1] and reg["y"][0] <= point[1] <= reg["y"][1]


def _mover(rng, cfg, fam, spots, span_s: float) -> dict | None:
    """A mover of the family's shapes on a straight horizontal path in the region, a plate
    facing O and every spot from both ends of it."""
    o = {"role": "target", **dr.sized(str(rng.choice(fam["shapes"])), rng, cfg)}
    start = dr.centre_in(rng, cfg)
    heading = dr.u(rng, (0.0, 2 * math.pi))
    length = dr.u(rng, fam["speed_m_s"]) * span_s
    end = start + length * np.array([math.cos(heading), math.sin(heading), 0.0])
    if not _in_region(end, cfg):
        return None
    middle = dr.placed(o, (start + end) / 2, rng, cfg, spots)
    if middle is None:
        return None
    for p in (start, end):  # the middle's orientation, checked at both ends
        moved = {**middle, "centre": p.tolist()}
        if dr.corners(moved)[:, 1].min() < cfg["region"]["wall_gap_m"]:
            return None
        if o["shape"] == "plate" and dr.families.facing_cos(
                np.asarray(middle["normal"]), p, spots) < cfg["region"]["min_facing_cos"]:
            return None
    return {**middle, "centre": np.round(start, 6).tolist(),
            "path": [np.round(start, 6).tolist(), np.round(end, 6).tolist()]}


def _clear_of(o: dict, movers, times, span_s: float, gap: float) -> bool:
    return all(np.linalg.norm(at(o, t, span_s) - at(m, t, span_s)) >=
               o["bound_m"] + m["bound_m"] + gap for m in movers for t in times)


def _furniture(rng, cfg, fam, spots, movers, times, span_s) -> dict | None:
    """A box or cabinet beside a mover's path: at a random point of it, across it by the two
    bounding radii and a gap drawn from gap_m, clear of every mover at every frame."""
    o = {"role": "furniture", **dr.sized(str(rng.choice(fam["furniture_shapes"])), rng, cfg)}
    m = movers[int(rng.integers(len(movers)))]
    a, b = (np.asarray(p, float) for p in m["path"])
    way = (b - a) / max(np.linalg.norm(b - a), 1e-9)
    side = np.cross([0.0, 0.0, 1.0], way) * (1 if rng.random() < 0.5 else -1)
    gap = dr.u(rng, fam["gap_m"])
    centre = a + (b - a) * rng.random() + side * (m["bound_m"] + o["bound_m"] + gap)
    centre[2] = dr.u(rng, cfg["region"]["z"])
    p = dr.placed(o, centre, rng, cfg, spots)
    if p is None or not _clear_of(p, movers, times, span_s, 0.05):
        return None
    return p


def sequence(rng, cfg, fam, cycle: int, lay) -> dict:
    """Movers (movers[cycle % len], apart from each other at every frame) and furniture."""
    spots = np.asarray(lay["spots"])
    span_s = (fam["frames"] - 1) / fam["fps"]
    times = np.arange(fam["frames"]) / fam["fps"]
    k = fam["movers"][cycle % len(fam["movers"])]

    def make_movers():
        out = []
        for _ in range(k):
            m = _mover(rng, cfg, fam, spots, span_s)
            if m is None or not _clear_of(m, out, times, span_s, 0.1):
                return None
            out.append(m)
        return out
    movers = dr.tries(make_movers, f"{k} movers")
    count = int(rng.integers(fam["furniture"][0], fam["furniture"][1] + 1))

    def make_furniture():
        out = []
        for _ in range(count):
            f = _furniture(rng, cfg, fam, spots, movers, times, span_s)
            if f is None or not all(dr.apart(f, g, 0.05) for g in out):
                return None
            out.append(f)
        return out
    furniture = dr.tries(make_furniture, "furniture")
    frames = {k: fam[k] for k in ("frames", "fps", "first_frame")}
    return {"objects": movers + furniture, "sequence": frames}
