"""Wall-spot layouts: where the detectors look on the relay wall (the plane y = 0).

Generators return (n, 3) arrays of spots for `Setup(detector_spots=...)` and scene files:
`line` (the paper's A, B, C), `circle` (spots around a centre), `spad_patch` (a rectangular
SPAD-array patch imaged onto the wall). `height_observable` says whether the spots, with the
laser spot, can see height: only when they do not all lie on one line with it (rotating the
scene about such a line changes no path length).
"""
from __future__ import annotations

import math

import numpy as np

from ..core.errors import require
from ..core.geometry import as_point
from ..core.limits import MAX_WALL_SPOTS, require_count


def _on_wall(centre, field) -> np.ndarray:
    c = as_point(centre, field)
    require(abs(c[1]) < 1e-9, field, f"must lie on the wall y = 0, got y = {c[1]}",
            "set its y coordinate to 0")
    return c


def _count(n, field, minimum=1) -> int:
    """A spot count: an integer from `minimum` to MAX_WALL_SPOTS (checked before any array)."""
    require(isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n >= minimum,
            field, f"must be an integer >= {minimum}, got {n!r}", f"pass e.g. {max(minimum, 3)}")
    return require_count(field, n, MAX_WALL_SPOTS, "wall spots", "pass fewer spots (a 1024 x "
                         "1024 SPAD array is the most)")


def _length(v, field) -> float:
    require(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            and v > 0, field, f"must be a positive length in metres, got {v!r}", "pass e.g. 0.5")
    return float(v)


def line(start, stop, count: int) -> np.ndarray:
    """`count` spots evenly from `start` to `stop` (both on the wall), ends included."""
    a, b = _on_wall(start, "line.start"), _on_wall(stop, "line.stop")
    n = _count(count, "line.count")
    require(n == 1 or np.linalg.norm(b - a) > 0, "line.stop", "equals line.start",
            "give the line two different ends")
    t = np.linspace(0.0, 1.0, n) if n > 1 else np.zeros(1)
    return a[None, :] + t[:, None] * (b - a)[None, :]


def circle(centre, radius_m: float, count: int, *, start_deg: float = 0.0) -> np.ndarray:
    """`count` spots evenly on a circle of `radius_m` in the wall plane (x, z) around `centre`."""
    c = _on_wall(centre, "circle.centre")
    r, n = _length(radius_m, "circle.radius_m"), _count(count, "circle.count")
    angle = math.radians(start_deg) + 2 * math.pi * np.arange(n) / n
    return c[None, :] + r * np.stack([np.cos(angle), np.zeros(n), np.sin(angle)], axis=1)


def spad_patch(centre, counts=(32, 32), pitch_m=(0.0375, 0.0375)) -> np.ndarray:
    """A rectangular SPAD-array patch imaged onto the wall: counts (along x, along z) spots at
    `pitch_m` spacing, centred on `centre`; row-major along x, then z."""
    c = _on_wall(centre, "spad_patch.centre")
    counts = np.broadcast_to(np.asarray(counts), (2,))
    pitch = np.broadcast_to(np.asarray(pitch_m, dtype=np.float64), (2,))
    # whole numbers only: int(2.7) would silently make a 2-spot side
    nx, nz = (_count(int(v) if float(v).is_integer() else v, "spad_patch.counts")
              for v in counts.tolist())
    _count(nx * nz, "spad_patch.counts")  # the patch as a whole
    px, pz = (_length(float(v), "spad_patch.pitch_m") for v in pitch)
    x = (np.arange(nx) - (nx - 1) / 2) * px
    z = (np.arange(nz) - (nz - 1) / 2) * pz
    xx, zz = np.meshgrid(x, z, indexing="ij")
    return c[None, :] + np.stack([xx.ravel(), np.zeros(xx.size), zz.ravel()], axis=1)


def height_observable(laser_spot, detector_spots, tolerance_m: float = 1e-6) -> bool:
    """False when the laser spot(s) and every detector spot lie on one line (height invisible).
    laser_spot: one (3,), or one per histogram (n, 3)."""
    pts = np.vstack([np.asarray(laser_spot, float).reshape(-1, 3),
                     np.asarray(detector_spots, float).reshape(-1, 3)])
    centred = pts - pts.mean(axis=0)
    if len(pts) < 3:
        return False
    singular = np.linalg.svd(centred, compute_uv=False)
    return bool(singular[1] > tolerance_m * max(1.0, singular[0]))
