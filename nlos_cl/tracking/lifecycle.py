"""A track's life: birth from a free measurement, confirmation after M hits in its first N
frames (`confirm=(M, N)`; deleted if it is not), deletion of a confirmed track after
`max_misses` frames in a row without a measurement, and each frame's history point and filter
record (the RTS smoother's input)."""
from __future__ import annotations

import itertools
from collections import deque

import numpy as np

from ..core.errors import require
from .track import Track


class Lifecycle:
    """Births, confirmations and deletions for one tracker (ids count from 1)."""

    def __init__(self, motion, dims: int, plane_z: float, *, confirm=(2, 3), max_misses=5,
                 max_history=None):
        require(isinstance(confirm, (tuple, list)) and len(confirm) == 2
                and all(isinstance(v, int) and v >= 1 for v in confirm)
                and confirm[0] <= confirm[1], "confirm",
                f"must be (M, N) with 1 <= M <= N, got {confirm!r}", "pass (2, 3)")
        self.motion, self.dims, self.plane_z = motion, dims, float(plane_z)
        self.confirm, self.max_misses = (int(confirm[0]), int(confirm[1])), int(max_misses)
        self.max_history = max_history
        self._ids = itertools.count(1)

    def birth(self, m, t: float, frame_index: int, numbered: bool = True) -> Track:
        """A tentative track at measurement m (confirmed at once where M = 1); numbered=False:
        id 0, no id used up (a re-acquisition candidate, nlos_cl.tracking.recovery)."""
        d = self.dims
        x, P = np.zeros(2 * d), np.zeros((2 * d, 2 * d))
        x[:d] = np.asarray(m.position[:d])
        if d == 3 and 2 not in m.axes:  # height not measured: start on the grid's middle
            x[2] = self.plane_z
        P[:d, :d] = np.diag(np.full(d, 4.0))  # unmeasured axes: +-2 m, the scale of a room
        P[np.ix_(m.axes, m.axes)] = m.R
        P[d:, d:] = self.motion.initial_speed_sigma ** 2 * np.eye(d)
        track = Track(next(self._ids) if numbered else 0, x, P, self.plane_z, t_s=t,
                      history=deque(maxlen=self.max_history),
                      steps=deque(maxlen=self.max_history))
        if self.confirm[0] <= 1:
            track.status = "confirmed"
        remember(track, True, frame_index)
        return track

    def account(self, track: Track, hit: bool, frame_index: int) -> bool:
        """Count a hit or a miss, confirm or delete, record the frame. True: now deleted."""
        track.age += 1
        track.hits += hit
        track.misses = 0 if hit else track.misses + 1
        m, n = self.confirm
        if track.status == "tentative" and track.hits >= m:
            track.status = "confirmed"
        elif track.status == "tentative" and track.age >= n:
            track.status = "deleted"
        elif track.status == "confirmed" and track.misses > self.max_misses:
            track.status = "deleted"
        remember(track, hit, frame_index)
        return track.status == "deleted"


def remember(track: Track, measured: bool, frame_index: int) -> None:
    """The frame's history point and filter record (state, covariance, the prediction)."""
    p = track.position
    track.history.append((frame_index, track.t_s, float(p[0]), float(p[1]), float(p[2]),
                          bool(measured)))
    dt, xp, Pp = track.pending or (np.nan, np.full_like(track.state, np.nan),
                                   np.full_like(track.covariance, np.nan))  # a birth
    track.steps.append(np.concatenate([track.state, track.covariance.ravel(), xp, Pp.ravel(),
                                       [dt]]))
    track.pending = None
