"""Moving targets: a piecewise-linear trajectory (waypoints in time) and a target that follows
one. The target's centre (its mesh's bounding-box centre) is put on the trajectory; the mesh is
translated, never rotated. Before the first waypoint and after the last the target stands still.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.errors import require


@dataclass(frozen=True, init=False)
class Trajectory:
    """Waypoints `positions` (K, 3) m at strictly increasing times `t_s` (K,) s, K >= 1;
    straight lines between them at constant speed. `at(t)` is the position at time t."""

    t_s: np.ndarray
    positions: np.ndarray

    def __init__(self, t_s, positions):
        t = np.array(t_s, dtype=np.float64).reshape(-1) if np.ndim(t_s) else \
            np.array([t_s], dtype=np.float64)
        p = np.array(positions, dtype=np.float64)
        if p.shape == (3,):
            p = p[None, :]
        require(t.size >= 1, "trajectory.t_s", "is empty", "pass one time per waypoint, e.g. "
                "[0, 5]")
        require(bool(np.all(np.isfinite(t))), "trajectory.t_s", f"contains NaN or inf: "
                f"{t.tolist()}", "pass finite times in seconds")
        require(bool(np.all(np.diff(t) > 0)), "trajectory.t_s", f"must increase strictly, got "
                f"{t.tolist()}", "sort the waypoints by time, one waypoint per time")
        require(p.ndim == 2 and p.shape[1] == 3, "trajectory.positions", f"expected shape "
                f"(n_waypoints, 3), got {p.shape}", "pass one [x, y, z] per waypoint")
        require(p.shape[0] == t.size, "trajectory.positions", f"{p.shape[0]} waypoints for "
                f"{t.size} times", "pass one position per time in t_s")
        require(bool(np.all(np.isfinite(p))), "trajectory.positions", "contains NaN or inf",
                "pass finite coordinates in metres")
        require(bool(np.all(p[:, 1] > 0)), "trajectory.positions", f"reaches y <= 0 (the wall "
                f"or behind it): y = {p[:, 1].tolist()}", "keep every waypoint in the hidden "
                "area y > 0")
        for name, value in (("t_s", t), ("positions", p)):
            value.flags.writeable = False
            object.__setattr__(self, name, value)

    @classmethod
    def from_mapping(cls, spec) -> "Trajectory":
        """From a scene file's `trajectory: {t_s: [0, 5], positions: [[2, 4, 0], [5, 1, 0]]}`."""
        require(isinstance(spec, dict) and "t_s" in spec and "positions" in spec, "trajectory",
                f"expected a mapping with t_s and positions, got {spec!r}",
                "write trajectory: {t_s: [0, 5], positions: [[2, 4, 0], [5, 1, 0]]}")
        return cls(spec["t_s"], spec["positions"])

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0])

    def at(self, t: float) -> np.ndarray:
        """(3,) position at time t (s); held at the first/last waypoint outside their span."""
        require(isinstance(t, (int, float, np.floating, np.integer)) and not isinstance(t, bool)
                and math.isfinite(float(t)), "t", f"must be a finite time in seconds, got {t!r}",
                "pass e.g. 0.5")
        return np.array([np.interp(float(t), self.t_s, self.positions[:, i]) for i in range(3)])

    def velocity(self, t: float) -> np.ndarray:
        """(3,) velocity (m/s) on the segment holding t (zero outside the waypoints' span)."""
        t = float(t)
        if self.t_s.size < 2 or t < self.t_s[0] or t >= self.t_s[-1]:
            return np.zeros(3)
        k = int(np.searchsorted(self.t_s, t, side="right")) - 1
        return (self.positions[k + 1] - self.positions[k]) / (self.t_s[k + 1] - self.t_s[k])


@dataclass(frozen=True)
class MovingTarget:
    """A nl.Target whose centre follows `trajectory` (its mesh is translated frame by frame)."""

    target: object  # nl.Target
    trajectory: Trajectory

    def __post_init__(self):
        from .scene import Target
        require(isinstance(self.target, Target), "moving.target", "expected a nlos_cl.Target, "
                f"got {type(self.target).__name__}", "wrap the mesh: nl.Target(mesh)")
        require(isinstance(self.trajectory, Trajectory), "moving.trajectory",
                f"expected a Trajectory, got {type(self.trajectory).__name__}",
                "pass Trajectory(t_s=[0, 5], positions=[[2, 4, 0], [5, 1, 0]])")

    @property
    def centre(self) -> np.ndarray:
        return self.target.mesh.bounds.mean(axis=0)

    def placed(self, t: float):
        """The target at time t: nl.Target(mesh.copy() translated onto the trajectory)."""
        from .scene import Target
        mesh = self.target.mesh.copy()
        mesh.apply_translation(self.trajectory.at(t) - self.centre)
        return Target(mesh, self.target.brdf)
