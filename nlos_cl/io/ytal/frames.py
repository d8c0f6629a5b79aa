"""A capture's own coordinate frame, and the wall-geometry rules for what a capture declares.

Internally the relay wall is y = 0, the hidden space y > 0 and z up. A file has its own frame:
y-tal's wall is Z = 0 with the hidden space at Z > 0 and Y up, mapped to ours by the proper
rotation (x, y, z) = (-X, Z, Y). Which way a lab's X points is not recorded in the format, so
no fixed mapping can put every target at positive x: the default region
(nlos_cl.localization.region) therefore covers both sides of every spot, and positions are reported
back in the file's own frame."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...core.errors import require
from ...core.geometry import coincident_pair
from ...core.grid import Grid
from ...core.histograms import HistogramSet

WALL_TOLERANCE_M = 0.01  # a spot this far off the wall biases the ellipse path by <= 1 cm


SAME_SPOT_M = 1e-4  # spots closer than this are one spot (float32 files resolve ~1e-6 m)


@dataclass(frozen=True)
class CaptureFrame:
    """A file's coordinate frame: internal = matrix @ file, a signed axis permutation."""

    name: str
    axes: tuple
    matrix: tuple  # 3 x 3, rows: internal axes in terms of the file's axes
    description: str

    def __post_init__(self):
        m = np.asarray(self.matrix, dtype=np.float64)
        require(m.shape == (3, 3) and np.allclose(np.abs(m).sum(axis=0), 1)
                and np.allclose(np.abs(m).sum(axis=1), 1) and np.allclose(np.abs(m).max(0), 1),
                "frame.matrix", "must be a signed permutation of the axes",
                "map each file axis to one internal axis, with a sign")
        object.__setattr__(self, "matrix", tuple(tuple(float(v) for v in row) for row in m))
        object.__setattr__(self, "axes", tuple(self.axes))

    def to_internal(self, points) -> np.ndarray:
        return np.asarray(points, dtype=np.float64) @ np.asarray(self.matrix).T

    def from_internal(self, points) -> np.ndarray:
        return np.asarray(points, dtype=np.float64) @ np.asarray(self.matrix)  # inverse = T

    def grid(self, ranges, step_m: float) -> Grid:
        """An internal Grid from inclusive (low, high) ranges along the file's three axes."""
        m = np.asarray(self.matrix)
        out = [None, None, None]
        for i, (name, rng) in enumerate(zip(self.axes, ranges)):
            lo, hi = (float(v) for v in rng)
            require(math.isfinite(lo) and math.isfinite(hi) and hi >= lo, f"grid.{name}",
                    f"range ({lo}, {hi}) is empty or inverted", "pass (low, high), high >= low")
            j = int(np.argmax(np.abs(m[:, i])))
            out[j] = (lo, hi) if m[j, i] > 0 else (-hi, -lo)
        d = int(np.argmax(np.abs(m[1])))
        require(out[1][0] > 0, f"grid.{self.axes[d]}", f"the range {tuple(ranges[d])} reaches "
                f"the wall or behind it (hidden space is {self.axes[d]} > 0 in the {self.name} "
                "frame)", f"start the {self.axes[d]} range above 0, e.g. at one step")
        return Grid.from_ranges(x=out[0], y=out[1], z=out[2], step_m=step_m)

    def ranges(self, grid: Grid) -> tuple:
        """The grid's (low, high) cell centres along the file's three axes."""
        lo = np.array([a[0] for a in grid.axes()])
        hi = np.array([a[-1] for a in grid.axes()])
        a, b = self.from_internal(lo), self.from_internal(hi)
        return tuple((float(min(p, q)), float(max(p, q))) for p, q in zip(a, b))

    def as_json(self) -> dict:
        return {"name": self.name, "axes": list(self.axes), "to_internal": [list(r) for r in
                self.matrix], "description": self.description}


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
    file's): on the wall within WALL_TOLERANCE_M, no two detectors on one spot, none on the
    laser spot. Paired (laser row k with spot row k): no two rows the same pair instead; a
    laser on its own spot is the confocal layout, and N lasers may share one detector."""
    laser = np.asarray(laser, dtype=np.float64).reshape(-1, 3)
    spots = np.asarray(spots, dtype=np.float64).reshape(-1, 3)
    wall = frame.axes[int(np.argmax(np.abs(np.asarray(frame.matrix)[1])))]
    for name, pts in ((laser_field, laser), (spots_field, spots)):
        off = np.abs(pts[:, 1])
        i = int(np.argmax(off))
        require(off[i] <= WALL_TOLERANCE_M, f"{prefix}{name}",
                f"point {i} {_fmt(frame.from_internal(pts[i]))} lies {off[i]:.3g} m off the "
                f"relay wall {wall} = 0 (tolerance {WALL_TOLERANCE_M} m), but the ellipse model "
                "puts every spot on the wall", f"store wall points with {wall} = 0 (shift the "
                f"file's frame so that the relay wall is the plane {wall} = 0)")
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
