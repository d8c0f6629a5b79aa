"""Where each located target shadows the search region from the laser spot: a point whose
straight path to the laser spot crosses a found target gets no light, so a second target there
returns none and the data cannot show it. The target is the box its fit gives (centre, its own
axes across / up / along the normal, its extent; a curved shape's inscribed box, so the shadow
claimed is one the target surely casts). Computed for a single laser spot (paired and confocal
captures light each spot from a different place: none is claimed there), and for fitted
targets only (the paper's argmax gives no size). The JSON states each shadow in the capture's
frame: the apex (the laser spot), the box, and the part of the search region it covers."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# The share of each half-size kept as the inscribed box (across, up, along the normal).
INSCRIBED = {"plate": (1.0, 1.0, 1.0), "box": (1.0, 1.0, 1.0),
             "cylinder": (math.sqrt(0.5), 1.0, math.sqrt(0.5)),
             "ellipsoid": (math.sqrt(1 / 3),) * 3,
             "capsule": (math.sqrt(1 / 3),) * 3}  # holds the ellipsoid of its size: its box
SAMPLES = 24  # points per axis of the search region tried for the shadow's bounds
RULE = ("a point whose straight path to the apex (the laser spot) crosses the box gets no "
        "light: a target there returns little or none")


def crosses(apex, points, centre, axes, half) -> np.ndarray:
    """Per point, whether the segment apex -> point passes through the box (centre, rows of
    `axes` its unit axes, `half` its half-sizes) and leaves it before the point: the point
    lies behind the box as the apex sees it. Any frame, as long as all share it."""
    axes = np.asarray(axes, float)
    q0 = (np.asarray(apex, float) - centre) @ axes.T
    d = (np.asarray(points, float).reshape(-1, 3) - centre) @ axes.T - q0
    half = np.asarray(half, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-half - q0) / d, (half - q0) / d
    flat = np.abs(d) < 1e-12  # parallel to this slab: inside it or never
    inside = np.abs(q0) <= half
    lo = np.where(flat, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2)).max(axis=1)
    hi = np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2)).min(axis=1)
    return (lo <= hi) & (lo > 0.0) & (hi < 1.0 - 1e-9)  # a point on the box is not behind it


@dataclass(frozen=True)
class Shadow:
    """Target `target`'s (1-based) shadow from `apex`; every vector in our frame."""

    target: int
    apex: np.ndarray
    centre: np.ndarray
    axes: np.ndarray  # rows: across, up, along the normal
    half: np.ndarray

    def hides(self, points) -> np.ndarray:
        return crosses(self.apex, points, self.centre, self.axes, self.half)

    def bounds(self, region) -> np.ndarray | None:
        """(lo, hi) per internal axis of the region's points this shadow hides, or None."""
        lo = np.asarray(region.origin, float)
        hi = lo + np.asarray(region.step) * (np.asarray(region.shape) - 1)
        axes = [np.linspace(a, b, SAMPLES if b > a else 1) for a, b in zip(lo, hi)]
        pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        hidden = pts[self.hides(pts)]
        return None if not len(hidden) else np.stack([hidden.min(0), hidden.max(0)])

    def as_json(self, frame, region) -> dict:
        """This shadow in `frame` (a CaptureFrame): apex, box and the region's part it hides
        (`region_part_m`: per file axis [low, high], None where it hides none of it)."""
        part = self.bounds(region)
        if part is not None:  # the part's corners, moved, give the file's bounds
            corners = np.array([[part[i][0], part[j][1], part[k][2]] for i in (0, 1)
                                for j in (0, 1) for k in (0, 1)])
            moved = frame.from_internal(corners)
            part = [[round(float(a), 3), round(float(b), 3)] for a, b in
                    zip(moved.min(0), moved.max(0))]
        return {"target": self.target, "apex": _r(frame.from_internal(self.apex)),
                "box": {"centre": _r(frame.from_internal(self.centre)),
                        "axes": [_r(v) for v in frame.direction_from_internal(self.axes)],
                        "half_m": _r(self.half)},
                "region_part_m": part, "rule": RULE}


def _r(v) -> list:
    return [round(float(x), 5) for x in np.asarray(v).ravel()]


def box_of(target):
    """(centre, axes, half) of a fitted target (ours), or None where it has no size."""
    fit, extent = target.fit, target.extent_m
    if fit is None or extent is None:
        return None
    n = np.asarray(fit.normal, float)
    n = n / np.linalg.norm(n)
    up = np.array([0.0, 0.0, 1.0])
    across = np.cross(up, n)
    if np.linalg.norm(across) < 1e-9:
        return None
    across /= np.linalg.norm(across)
    up = np.cross(n, across)
    keep = np.asarray(INSCRIBED.get(fit.shape, (0.0, 0.0, 0.0)))
    half = 0.5 * np.asarray(extent, float) * keep
    return np.asarray(target.position, float), np.stack([across, up, n]), half


def shadows(targets, laser_spot) -> list:
    """Each fitted target's Shadow from a single laser spot (none for paired captures)."""
    if np.ndim(laser_spot) != 1:
        return []
    out = []
    for i, t in enumerate(targets, 1):
        box = box_of(t)
        if box is not None and float(box[2][:2].min()) > 0:
            out.append(Shadow(i, np.asarray(laser_spot, float), *box))
    return out
