"""Small geometric types and validators shared by the scene, the meshes, the grid and the
model fits (no trimesh here: what only needs facets stays light)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import require


def coincident_pair(points, tolerance_m: float):
    """The first pair (i, j), i < j, of points closer than `tolerance_m`, or None, without the
    n x n distance matrix (a 128 x 128 SPAD patch would need 2 GiB): sorted along x, a point can
    only coincide with the few that follow it within the tolerance in x."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    order = np.argsort(points[:, 0], kind="stable")
    ordered = points[order]
    for k in range(1, len(points)):
        near_in_x = ordered[k:, 0] - ordered[:-k, 0] <= tolerance_m
        if not near_in_x.any():
            return None
        close = near_in_x & (np.linalg.norm(ordered[k:] - ordered[:-k], axis=1) <= tolerance_m)
        if close.any():
            i = int(np.argmax(close))
            return tuple(sorted((int(order[i]), int(order[i + k]))))
    return None


def as_point(value, field_name: str) -> np.ndarray:
    """A finite [x, y, z] as our own float64 copy (the caller's array is never aliased)."""
    arr = np.array(value, dtype=np.float64)
    require(arr.shape == (3,), field_name, f"expected a point [x, y, z], got shape {arr.shape}",
            "pass three coordinates in metres")
    require(bool(np.all(np.isfinite(arr))), field_name, f"non-finite coordinate {arr.tolist()}",
            "pass finite coordinates in metres")
    return arr


@dataclass(frozen=True)
class Facets:
    """A target cut into small flat pieces: centre, outward unit normal, area (m^2)."""

    centres: np.ndarray
    normals: np.ndarray
    areas: np.ndarray

    @property
    def count(self) -> int:
        return self.areas.shape[0]

    def take(self, which) -> "Facets":
        """The facets `which` selects (a bool mask or indices), in that order, contiguous."""
        return Facets(*(np.ascontiguousarray(v[which])
                        for v in (self.centres, self.normals, self.areas)))


def morton_order(points: np.ndarray) -> np.ndarray:
    """Indices that sort points along a Z-order curve (10 bits per axis): neighbours in space
    end up near each other in memory (facet chunks, ray-test clusters)."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    q = ((points - lo) / np.maximum(hi - lo, 1e-12) * 1023).astype(np.uint64)
    code = np.zeros(len(points), dtype=np.uint64)
    for bit in range(10):
        for axis in range(3):
            code |= ((q[:, axis] >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + axis)
    return np.argsort(code, kind="stable")


def farthest_points(points, k: int) -> np.ndarray:
    """Indices of k of the points spread over them (greedy farthest-point sampling, from the
    point nearest their mean), sorted. Index strides are no substitute: on a raster scan every
    64th point of 64 x 64 lies on one diagonal line, which hides the height."""
    pts = np.asarray(points, dtype=np.float64).reshape(len(points), -1)
    if k >= len(pts):
        return np.arange(len(pts))
    chosen = [int(np.argmin(np.linalg.norm(pts - pts.mean(axis=0), axis=1)))]
    gap = np.linalg.norm(pts - pts[chosen[0]], axis=1)
    for _ in range(k - 1):
        chosen.append(int(np.argmax(gap)))
        gap = np.minimum(gap, np.linalg.norm(pts - pts[chosen[-1]], axis=1))
    return np.sort(np.array(chosen))


def distance(a, b):
    """|a - b| over the last axis (3), component by component: np.linalg.norm's numbers
    without its checks, and without a reduction over an axis of 3 (half the time)."""
    dx, dy, dz = a[..., 0] - b[..., 0], a[..., 1] - b[..., 1], a[..., 2] - b[..., 2]
    dx *= dx
    dy *= dy
    dz *= dz
    dx += dy
    dx += dz
    return np.sqrt(dx, out=dx)


def spot_legs(px, py, pz, spots):
    """The legs from points to every wall spot, component by component (spots (D, 3); the
    points' coordinates broadcast against (D, 1, 1)): v2 = S - P as (v2x, v2y, v2z) and
    |v2|^2, each (D, ...)."""
    sx, sy, sz = (spots[:, k, None, None] for k in range(3))
    v2x, v2y, v2z = sx - px, sy - py, sz - pz
    r2sq = v2x * v2x
    r2sq += v2y * v2y
    r2sq += v2z * v2z
    return v2x, v2y, v2z, r2sq
