"""A followed target's state and record (`Track`), and its record smoothed offline
(Rauch-Tung-Striebel, `Track.smoothed`)."""
from __future__ import annotations

import itertools
import math
from collections import deque
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from . import kalman
from .motion import ConstantVelocity

DEPTH_MEMORY = 20  # closed depths a track keeps (tracking.depth)
SIZE_MEMORY = 20  # recent plate sizes seen whole a track keeps (its size prior: tracking.warm)

@dataclass
class Track:
    """A followed target. state: (p, v) (2d,), covariance (2d, 2d); status 'tentative',
    'confirmed' or 'deleted'; history: (frame, t_s, x, y, z, measured) per frame since birth;
    steps: the filter's own record per frame (for `smoothed()`), as long as the history: one
    packed float64 array each (x, P, predicted x, predicted P, dt), ~0.4 kB in 2D. plate: the
    plate row (x, y, z, width, height, yaw) of the last measurement paired with it, where that
    was a model estimator's plate fit (the next frame's warm start)."""

    id: int
    state: np.ndarray
    covariance: np.ndarray
    plane_z: float
    status: str = "tentative"
    hits: int = 1
    misses: int = 0
    age: int = 1
    t_s: float = 0.0
    history: deque = field(default_factory=deque)
    steps: deque = field(default_factory=deque)
    pending: tuple | None = None  # (dt, x, P) of the last prediction, until it is recorded
    plate: np.ndarray | None = None  # the last paired fit's row (warm starts)
    model: str = "plate"  # its shape: "plate", or a closed family (tracking.warm.prior)
    # the rows of plates touching it in that fit: its object's other faces or light, which
    # the warm fits carry (tracking.association.objects)
    extra: list = field(default_factory=list)
    # the Birge ratio of the last cold fit behind its measurements (Prior.misfit: warm.keep)
    misfit: float | None = None
    late: bool = False  # that cold fit kept late copies of the light (Prior.late)
    # (width, height) of the recent paired plate fits that saw the plate whole, or the first
    # plate's alone until one did (size_seeded): the size prior of warm fits (warm.remember)
    sizes: deque = field(default_factory=lambda: deque(maxlen=SIZE_MEMORY))
    size_seeded: bool = False
    # (depth, sd) of the closed shapes paired with it, and where its last measurement lay from
    # its plate (tracking.depth: a closed object's centre behind the plate a warm fit finds)
    depths: deque = field(default_factory=lambda: deque(maxlen=DEPTH_MEMORY))
    offset: np.ndarray | None = None
    # under an IMM (motion.Interacting): the modes whose mixture is state/covariance (valid
    # while those equal modes_of, copies of the mixture's: a state set or edited otherwise,
    # e.g. by a re-acquisition, restarts the modes), and this frame's predicted modes (the
    # gate's); None under one model
    modes: object = None
    modes_of: object = None
    predicted_modes: object = None

    @property
    def dims(self) -> int:
        return len(self.state) // 2

    @property
    def position(self) -> np.ndarray:
        p = np.full(3, self.plane_z)
        p[:self.dims] = self.state[:self.dims]
        return p

    @property
    def velocity(self) -> np.ndarray:
        v = np.zeros(3)
        v[:self.dims] = self.state[self.dims:]
        return v

    @property
    def position_covariance(self) -> np.ndarray:
        """(3, 3) m^2; a 2D track's z is not estimated: infinite variance, no correlation."""
        d, c = self.dims, np.zeros((3, 3))
        c[:d, :d] = self.covariance[:d, :d]
        if d == 2:
            c[2, 2] = math.inf
        return c

    def smoothed(self, last: int | None = None) -> list:
        """The track's history smoothed offline (Rauch-Tung-Striebel, the filter's own model):
        a `Smoothed(frame, t_s, position, covariance, velocity)` per frame of the history, each
        using the frames after it as well. Costs one small solve per frame. last: only the
        last `last` frames (the backward pass needs nothing older: the first of them is the
        fixed-lag estimate, `Tracker.lagged`). A re-acquired track's record (no prediction
        into the frame it was re-found at: nlos_cl.tracking.recovery) is smoothed in segments."""
        d = self.dims
        n = 2 * d
        steps, history = _tail(self.steps, last), _tail(self.history, last)
        filtered, predicted, smooth = [], [], []
        for k, row in enumerate(steps):  # unpack: x (n), P (n^2), x_pred (n), P_pred (n^2), dt
            if k and not math.isfinite(row[-1]):  # a restart: what came before, smoothed alone
                smooth += kalman.rts_smooth(filtered, predicted)
                filtered, predicted = [], []
            filtered.append((row[:n], row[n:n + n * n].reshape(n, n)))
            predicted.append((ConstantVelocity.transition(row[-1], d),
                              row[n + n * n:2 * n + n * n], row[2 * n + n * n:-1].reshape(n, n)))
        smooth += kalman.rts_smooth(filtered, predicted)
        out = []
        for h, (x, P) in zip(history, smooth):
            view = Track(self.id, x, P, self.plane_z)
            out.append(Smoothed(h[0], h[1], view.position, view.position_covariance,
                                view.velocity))
        return out


def _tail(record: deque, last: int | None) -> list:
    """The last `last` entries (all if None), read from the right: O(last), not O(len)."""
    if last is None:
        return list(record)
    return list(itertools.islice(reversed(record), last))[::-1]


class Smoothed(NamedTuple):
    """One frame of a smoothed track (Track.smoothed()); covariance of the position, m^2."""

    frame: int
    t_s: float
    position: np.ndarray
    covariance: np.ndarray
    velocity: np.ndarray
