"""A capture's own coordinate frame, and the wall-geometry rules for what a capture declares.

Internally the relay wall is y = 0, the hidden space y > 0 and z up. A file has its own frame:
y-tal's wall is Z = 0 with the hidden space at Z > 0 and Y up, mapped to ours by the proper
rotation (x, y, z) = (-X, Z, Y) (YTAL). A file whose wall points are not on Z = 0 (a tilted or
moved wall, measured points a few cm off a plane) gets a frame fitted to them (wall.py):
internal = R (file - origin), R any rotation. Which way a lab's X points is not recorded in the
format, so no fixed mapping can put every target at positive x: the default region
(nlos_cl.localization.region) therefore covers both sides of every spot, and positions are
reported back in the file's own frame."""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from ...core.errors import require
from ...core.geometry import coincident_pair
from ...core.grid import Grid
from ...core.histograms import HistogramSet

ON_PLANE_Z_M = 0.01  # wall points this close to Z = 0 keep YTAL exactly (what was read before)
# A wall point may leave the fitted plane by this much and is used as it is (the ellipse path
# |c - O| + |c - D| needs no plane): measured, calibrated walls lie up to 3 cm off one; farther
# than 5 cm no plane describes the wall (a corner, two surfaces, a wrong point).
WALL_TOLERANCE_M = 0.05


SAME_SPOT_M = 1e-4  # spots closer than this are one spot (float32 files resolve ~1e-6 m)


@dataclass(frozen=True)
class CaptureFrame:
    """A file's coordinate frame: internal = matrix @ (file - origin). matrix: a proper
    rotation, its rows the internal axes in the file's (a signed permutation for YTAL);
    origin: the internal origin in file coordinates (a point on the relay wall)."""

    name: str
    axes: tuple
    matrix: tuple  # 3 x 3, rows: internal axes in terms of the file's axes
    description: str
    origin: tuple = field(default=(0.0, 0.0, 0.0))

    def __post_init__(self):
        m = np.asarray(self.matrix, dtype=np.float64)
        o = np.asarray(self.origin, dtype=np.float64)
        ok = m.shape == (3, 3) and bool(np.all(np.isfinite(m)))
        require(ok and np.allclose(m @ m.T, np.eye(3), rtol=0, atol=1e-9)
                and np.linalg.det(m) > 0, "frame.matrix", "must be a rotation (orthonormal "
                "rows, determinant +1)", "give the internal axes as right-handed orthonormal "
                "rows in the file's axes")
        require(o.shape == (3,) and bool(np.all(np.isfinite(o))), "frame.origin",
                f"must be one finite (x, y, z) point, got {self.origin!r}", "pass 3 numbers")
        object.__setattr__(self, "matrix", tuple(tuple(float(v) for v in row) for row in m))
        object.__setattr__(self, "origin", tuple(float(v) for v in o))
        object.__setattr__(self, "axes", tuple(self.axes))

    @property
    def is_permutation(self) -> bool:
        """Each internal axis is one file axis (with a sign): grids and maps align."""
        m = np.abs(np.asarray(self.matrix))
        return bool(np.all((m == 0) | (m == 1)))

    def to_internal(self, points) -> np.ndarray:
        p = np.asarray(points, dtype=np.float64)
        return (p - np.asarray(self.origin) if any(self.origin) else p) @ np.asarray(self.matrix).T

    def from_internal(self, points) -> np.ndarray:
        p = np.asarray(points, dtype=np.float64) @ np.asarray(self.matrix)  # inverse = T
        return p + np.asarray(self.origin) if any(self.origin) else p

    def direction_from_internal(self, vectors) -> np.ndarray:
        """A direction or velocity (no origin): rotated only."""
        return np.asarray(vectors, dtype=np.float64) @ np.asarray(self.matrix)

    def _hidden(self) -> str:
        m, o = np.asarray(self.matrix), np.asarray(self.origin)
        if self.is_permutation:
            d = int(np.argmax(np.abs(m[1])))
            return f"{self.axes[d]} {'>' if m[1, d] > 0 else '<'} {o[d] + 0.0:.4g}"
        n = ", ".join(f"{v:.4g}" for v in m[1])
        return f"in front of the wall through {_fmt(o)} with normal ({n})"

    def grid(self, ranges, step_m: float) -> Grid:
        """An internal Grid from inclusive (low, high) ranges along the file's three axes: for a
        rotation that is not a permutation, the internal box around the file box's corners, cut
        at the wall (one step in front of it)."""
        lows, highs = [], []
        for name, rng in zip(self.axes, ranges):
            lo, hi = (float(v) for v in rng)
            require(math.isfinite(lo) and math.isfinite(hi) and hi >= lo, f"grid.{name}",
                    f"range ({lo}, {hi}) is empty or inverted", "pass (low, high), high >= low")
            lows.append(lo)
            highs.append(hi)
        if not self.is_permutation:
            return self._rotated_grid(ranges, lows, highs, step_m)
        m, o = np.asarray(self.matrix), self.origin
        out = [None, None, None]
        for i in range(3):
            lo, hi = lows[i] - o[i], highs[i] - o[i]
            j = int(np.argmax(np.abs(m[:, i])))
            out[j] = (lo, hi) if m[j, i] > 0 else (-hi, -lo)
        d = int(np.argmax(np.abs(m[1])))
        require(out[1][0] > 0, f"grid.{self.axes[d]}", f"the range {tuple(ranges[d])} reaches "
                f"the wall or behind it (hidden space is {self._hidden()} in the {self.name} "
                "frame)", f"start the {self.axes[d]} range {'above' if m[1, d] > 0 else 'below'} "
                f"{o[d] + 0.0:.4g}, e.g. at one step")
        return Grid.from_ranges(x=out[0], y=out[1], z=out[2], step_m=step_m)

    def _rotated_grid(self, ranges, lows, highs, step_m) -> Grid:
        inner = self.to_internal(list(itertools.product(*zip(lows, highs))))
        lo, hi = inner.min(axis=0), inner.max(axis=0)
        require(hi[1] >= step_m, "grid", f"the box {[tuple(r) for r in ranges]} lies behind "
                f"the wall (hidden space is {self._hidden()} in the {self.name} frame)",
                "give ranges that reach in front of the wall")
        lo[1] = max(lo[1], step_m)
        return Grid.from_ranges(*zip(lo, hi), step_m=step_m)

    def ranges(self, grid: Grid) -> tuple:
        """The grid's (low, high) cell centres along the file's three axes (for a rotation that
        is not a permutation, the file box around the grid's corners)."""
        ends = [(a[0], a[-1]) for a in grid.axes()]
        pts = self.from_internal(list(itertools.product(*ends)))
        return tuple((float(p), float(q)) for p, q in zip(pts.min(axis=0), pts.max(axis=0)))

    def as_json(self) -> dict:
        return {"name": self.name, "axes": list(self.axes), "to_internal": [list(r) for r in
                self.matrix], "origin": list(self.origin),
                "internal": "to_internal @ (file - origin)", "description": self.description}


INTERNAL = CaptureFrame("nlos_cl", ("x", "y", "z"), np.eye(3),
                        "nlos_cl's frame: relay wall y = 0, hidden space y > 0, z up")


YTAL = CaptureFrame("ytal", ("X", "Y", "Z"), [[-1, 0, 0], [0, 0, 1], [0, 1, 0]],
                    "the capture file's (y-tal) frame: relay wall Z = 0, hidden space Z > 0, "
                    "Y up; nlos_cl's internal (x, y, z) = (-X, Z, Y)")


def to_ytal(points) -> np.ndarray:
    return YTAL.from_internal(points)


def from_ytal(points) -> np.ndarray:
    return YTAL.to_internal(points)


def check_wall_spots(laser, spots, frame: CaptureFrame = INTERNAL, *, paired=False,
                     laser_field="laser_spot", spots_field="detector_spots", prefix="") -> None:
    """nl.Setup's rules for spots a file declares (internal coordinates, messages in the
    file's): on the wall (within WALL_TOLERANCE_M of the frame's wall plane; the ellipse path
    uses them where they are), no two detectors on one spot, none on the laser spot. Paired
    (laser row k with spot row k): no two rows the same pair instead; a laser on its own spot is
    the confocal layout, and N lasers may share one detector."""
    laser = np.asarray(laser, dtype=np.float64).reshape(-1, 3)
    spots = np.asarray(spots, dtype=np.float64).reshape(-1, 3)
    for name, pts in ((laser_field, laser), (spots_field, spots)):
        off = np.abs(pts[:, 1])
        i = int(np.argmax(off))
        require(off[i] <= WALL_TOLERANCE_M, f"{prefix}{name}",
                f"point {i} {_fmt(frame.from_internal(pts[i]))} lies {off[i]:.3g} m off the "
                f"relay wall (the plane fitted through the wall points; tolerance "
                f"{WALL_TOLERANCE_M} m): no one plane holds the wall", "store the points of "
                f"one flat relay wall, each within {WALL_TOLERANCE_M * 100:g} cm of one plane "
                "(drop points on other surfaces)")
    if paired:
        _check_pairs(laser, spots, frame, spots_field, prefix)
        return
    pair = coincident_pair(spots, SAME_SPOT_M)
    require(pair is None, f"{prefix}{spots_field}",
            "points {} and {} are the same spot {}, so their ellipses carry the same "
            "information".format(*(pair or (0, 0)), _fmt(frame.from_internal(spots[pair[0]]))
                                 if pair else ""), "give every detector its own spot on the wall")
    gap = (np.linalg.norm(spots[None, :, :] - laser[:, None, :], axis=2).min(axis=1)
           if len(spots) else np.array([np.inf]))
    require(bool(np.all(gap > SAME_SPOT_M)), f"{prefix}{spots_field}",
            f"a detector spot coincides with the laser spot {_fmt(frame.from_internal(laser[0]))}"
            " (the direct wall return would swamp it)", "move that sensor point off the laser "
            "point, or drop it")


def _check_pairs(laser, spots, frame, spots_field, prefix) -> None:
    """Two rows with the same (laser, detector) pair carry the same information. Pairs are
    compared on a SAME_SPOT_M lattice (a pair a hair across a cell edge is missed; float32
    files resolve ~1e-6 m, so repeated points land in one cell)."""
    keys = np.round(np.hstack([laser, spots]) / SAME_SPOT_M)
    _, first, counts = np.unique(keys, axis=0, return_index=True, return_counts=True)
    require(bool(np.all(counts == 1)), f"{prefix}{spots_field}",
            f"{int((counts > 1).sum())} laser/sensor pairs appear twice (e.g. row "
            f"{int(first[np.argmax(counts > 1)]) if len(counts) else 0}: laser "
            f"{_fmt(frame.from_internal(laser[first[np.argmax(counts > 1)]]))}), so their "
            "ellipses carry the same information", "keep each laser/sensor pair once (sum "
            "repeated measurements)")


def require_locatable(histograms: HistogramSet, field: str = "histograms.detector_spots"
                      ) -> None:
    """Refuse a layout that cannot determine a position: one detector gives one ellipsoid, and
    every point on it fits the data equally well."""
    require(histograms.n_detectors >= 2, field, "has a single detector: every point of its "
            "ellipse fits the data equally well, so the position is underdetermined",
            "record with 2 or more detector spots (3 or more, not all on one line with the laser "
            "spot, to see height); one confocal spot's range: "
            "localization.ranges.confocal_range, or `nlos-cl track` on a sequence of it")


def _fmt(p) -> str:
    return "(" + ", ".join(f"{v:.4g}" for v in np.ravel(p)) + ")"
