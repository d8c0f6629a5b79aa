"""`Tracker`: hidden targets followed over frames, with identities.

Per frame: (background removal) -> nl.GaussFilter -> nl.Locator (plans built once) -> the
estimator's targets become measurements (nlos_cl.tracking.kalman.measurement) -> every live
track is predicted to the frame's time with the constant-velocity model -> measurements are
screened and paired with tracks (nlos_cl.tracking.association: vague, misfit and duplicate fits
out; SciPy's linear_sum_assignment on the squared Mahalanobis distance inside a chi-square gate;
one blob for two tracks updates neither) -> paired tracks are updated, the others coast on
their prediction -> measurements left over start tentative tracks (while fewer than
`max_tracks` are alive). A tentative track is confirmed after M hits in its first N frames
(`confirm=(M, N)`) and deleted if it is not; a confirmed track is deleted after `max_misses`
frames in a row without a measurement. Identities survive crossings because the assignment
compares measurements with each track's *predicted* position and covariance, and tracks coast
where the measurements cannot tell the targets apart. `smooth()`: the offline RTS smoother
over every track's record.
"""
from __future__ import annotations

import itertools
import math
from collections import deque
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..core.constants import PAPER_H_S
from ..core.errors import InputError, require
from . import association, kalman, warm
from .kalman import ConstantVelocity

NO_SIGNAL = "no cell has a non-zero likelihood"


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
    plate: np.ndarray | None = None  # the last paired fit's plate row (warm starts)

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
        fixed-lag estimate, `Tracker.lagged`)."""
        d = self.dims
        n = 2 * d
        steps, history = _tail(self.steps, last), _tail(self.history, last)
        filtered, predicted = [], []
        for row in steps:  # unpack: x (n), P (n^2), x_pred (n), P_pred (n^2), dt
            filtered.append((row[:n], row[n:n + n * n].reshape(n, n)))
            predicted.append((kalman.ConstantVelocity.transition(row[-1], d),
                              row[n + n * n:2 * n + n * n], row[2 * n + n * n:-1].reshape(n, n)))
        smooth = kalman.rts_smooth(filtered, predicted)
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


class Tracker:
    """`Tracker(layout, grid, estimator='paper'|'model'|object, motion=ConstantVelocity())`;
    `update(frame, t_s=None) -> list[Track]` (the live tracks, confirmed and tentative).

    layout: a nl.Layout or anything with `.layout` (HistogramSet, Signals, a read Sequence).
    frame: a HistogramSet (uploaded) or Signals, unfiltered. t_s: the frame's time (default:
    the previous one + frame_interval_s). background: a BackgroundRemover or None. max_tracks:
    how many targets may be followed at once (the model estimator finds several with
    estimator=ModelEstimator(targets=K)). warm_start: with the model estimator (a fixed
    number of targets), fit each frame from the confirmed tracks' last plates moved to their
    predictions (nlos_cl.tracking.warm; ~10x faster), else from the data alone. See the module
    docstring for the rest."""

    def __init__(self, layout, grid=None, *, estimator="paper", motion=None,
                 h_s: float = PAPER_H_S, log_mode: bool | None = None, background=None,
                 max_tracks: int = 1, gate_probability: float = 0.999,
                 fallback_sigma_m: float = 0.05, min_sigma_m: float = 0.002,
                 confirm=(2, 3), max_misses: int = 5, frame_interval_s: float = 0.1,
                 max_history: int | None = None, backend=None, search="auto",
                 max_sigma_m: float | None = 0.5, max_birge_ratio: float | None = None,
                 warm_start: bool = True):
        from ..localization.estimators import as_estimator
        from ..core.grid import Grid
        from ..localization.filter import GaussFilter
        from ..localization.locator import Locator
        layout = getattr(layout, "layout", layout)
        grid = Grid() if grid is None else grid
        motion = ConstantVelocity() if motion is None else motion
        require(isinstance(motion, ConstantVelocity), "motion", f"expected a ConstantVelocity,"
                f" got {type(motion).__name__}", "pass ConstantVelocity(accel_sigma=0.5)")
        _check_options(max_tracks, gate_probability, fallback_sigma_m, min_sigma_m, confirm,
                       max_misses, frame_interval_s, max_sigma_m, max_birge_ratio)
        log_mode = layout.n_detectors > 4 if log_mode is None else bool(log_mode)
        self.gauss = GaussFilter(h_s, layout.time_axis, backend=backend)
        self.estimator = as_estimator(estimator)
        # warm starts (nlos_cl.tracking.warm): the Locator calls the estimator through this
        self._started = warm.StartedEstimator(self.estimator) if warm_start and \
            warm.can_start(self.estimator) else None
        self.locator = Locator(layout, grid, estimator=self._started or self.estimator,
                               log_mode=log_mode, backend=backend, search=search)
        self.layout, self.grid, self.motion, self.background = layout, grid, motion, background
        self.dims = motion.dims or (3 if grid.shape[2] > 1 else 2)
        self.plane_z = float(grid.origin[2] + 0.5 * (grid.shape[2] - 1) * grid.step[2])
        self.max_tracks, self.gate_probability = int(max_tracks), float(gate_probability)
        self.fallback_sigma_m, self.min_sigma_m = float(fallback_sigma_m), float(min_sigma_m)
        self.confirm, self.max_misses = (int(confirm[0]), int(confirm[1])), int(max_misses)
        self.frame_interval_s, self.max_history = float(frame_interval_s), max_history
        self.backend, self.max_sigma_m, self.max_birge_ratio = backend, max_sigma_m, \
            max_birge_ratio
        from ..physics.layouts import height_observable
        self.height_observable = height_observable(layout.laser_spot, layout.detector_spots)
        self.tracks: list[Track] = []  # live
        self.finished: list[Track] = []  # deleted, most recent last (at most 100 kept)
        self.frame_index, self.t_s = -1, None
        # the last frame's Location, measurements and filtered Signals (a display's joint map)
        self.last_location, self.last_measurements, self.last_filtered = None, [], None
        self._ids = itertools.count(1)

    def smooth(self) -> dict:
        """Every track seen so far (live, then the last 100 deleted) smoothed offline:
        {id: Track.smoothed()}. The causal filter's states (`update`) are left as they are."""
        return {t.id: t.smoothed() for t in self.finished + self.tracks}

    def lagged(self, lag: int) -> dict:
        """Fixed-lag smoothing, for real time with a latency of `lag` frames: {id: Smoothed}
        of each live track at the frame `lag` frames before its last (or at its first frame,
        if younger), using every frame since. Exactly what `smooth()` would say of that frame
        now; O(lag) per track and call."""
        require(isinstance(lag, int) and lag >= 0, "lag", f"must be a whole number of frames "
                f">= 0, got {lag!r}", "pass e.g. 3 (0: the filter's own state)")
        return {t.id: t.smoothed(last=lag + 1)[0] for t in self.tracks if t.steps}

    # ------------------------------------------------------------------ per frame
    def update(self, frame, t_s: float | None = None) -> list[Track]:
        """Locate in `frame` and advance every track to its time."""
        t = self._next_time(t_s)
        return self.step(self.measure(frame, t), t)

    def step(self, measurements, t_s: float | None = None) -> list[Track]:
        """Advance the tracks with given measurements: kalman.Measurements or LocatedTargets
        (positions with or without covariance), e.g. from another localization pipeline."""
        t = self._next_time(t_s)
        measurements = [m if isinstance(m, kalman.Measurement) else kalman.measurement(
            m, self.dims, fallback_sigma_m=self.fallback_sigma_m, min_sigma_m=self.min_sigma_m,
            height_observable=self.height_observable) for m in measurements]
        self.frame_index += 1
        for track in self.tracks:
            self._predict(track, t)
        measurements = association.screen(
            measurements, max_sigma_m=self.max_sigma_m, max_birge_ratio=self.max_birge_ratio,
            gate_probability=self.gate_probability)
        pairs, free = association.associate(self.tracks, measurements, self.gate_probability)
        for track, m in pairs:
            track.state, track.covariance = kalman.update(track.state, track.covariance, m)
            track.plate = warm.plate_of(m)
        paired = {id(tr) for tr, _ in pairs}
        for track in list(self.tracks):
            self._account(track, id(track) in paired)
        for m in free:
            if len(self.tracks) < self.max_tracks:
                self.tracks.append(self._birth(m, t))
        self.t_s = t
        return list(self.tracks)

    def measure(self, frame, t_s: float | None = None) -> list:
        """The frame's located targets as Kalman measurements ([] if it holds no signal).
        t_s: the frame's time; with it (as `update` passes it) the model estimator is
        warm-started from the confirmed tracks' predictions (nlos_cl.tracking.warm)."""
        from ..ops.signals import as_signals
        sig = as_signals(frame, self.backend)
        if self.background is not None:
            sig = self.background(sig)
            if getattr(self.background, "alpha", 0) > 0 and self.background.frames_seen == 1:
                self.last_location, self.last_measurements, self.last_filtered = None, [], None
                return []  # a running mean's first frame: nothing learnt to subtract yet
        predicted = None
        if self._started is not None and t_s is not None:
            predicted = warm.predictions(self.tracks, t_s, self.motion, self.estimator.targets)
        location, found = self._locate(sig, predicted)
        if predicted is not None and warm.outside_gates(found, predicted,
                                                        self.gate_probability):
            location, found = self._locate(sig, None)  # another basin: fit this frame cold
        self.last_location, self.last_measurements = location, found
        return found

    def _locate(self, sig, predicted):
        """(Location or None, measurements), warm-started from `predicted` where given."""
        if self._started is not None:
            self._started.start = None if predicted is None else warm.start_rows(predicted)
        try:
            self.last_filtered = self.gauss(sig)
            location = self.locator(self.last_filtered, raw=sig)
        except InputError as exc:
            if NO_SIGNAL not in str(exc):
                raise
            location = None
        finally:
            if self._started is not None:
                self._started.start = None
        targets = [] if location is None else location.targets
        return location, [kalman.measurement(
            tg, self.dims, fallback_sigma_m=self.fallback_sigma_m, min_sigma_m=self.min_sigma_m,
            height_observable=self.height_observable) for tg in targets]

    # ------------------------------------------------------------------ pieces
    def _next_time(self, t_s):
        if t_s is None:
            return 0.0 if self.t_s is None else self.t_s + self.frame_interval_s
        require(isinstance(t_s, (int, float, np.floating)) and math.isfinite(float(t_s))
                and (self.t_s is None or float(t_s) > self.t_s), "t_s",
                f"must be a finite time after the previous frame's ({self.t_s}), got {t_s!r}",
                "pass increasing frame timestamps in seconds")
        return float(t_s)

    def _predict(self, track: Track, t: float):
        dt = t - track.t_s
        d = track.dims
        F = self.motion.transition(dt, d)
        track.state, track.covariance = kalman.predict(
            track.state, track.covariance, F, self.motion.process_noise(dt, d))
        track.t_s, track.pending = t, (dt, track.state, track.covariance)

    def _account(self, track: Track, hit: bool):
        """Hits and misses, confirmation and deletion; the history point."""
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
        self._remember(track, hit)
        if track.status == "deleted":
            self.tracks.remove(track)
            self.finished = (self.finished + [track])[-100:]

    def _remember(self, track: Track, measured: bool):
        p = track.position
        track.history.append((self.frame_index, track.t_s, float(p[0]), float(p[1]),
                              float(p[2]), bool(measured)))
        dt, xp, Pp = track.pending or (np.nan, np.full_like(track.state, np.nan),
                                       np.full_like(track.covariance, np.nan))  # a birth
        track.steps.append(np.concatenate([track.state, track.covariance.ravel(), xp,
                                           Pp.ravel(), [dt]]))
        track.pending = None

    def _birth(self, m, t) -> Track:
        d = self.dims
        x, P = np.zeros(2 * d), np.zeros((2 * d, 2 * d))
        x[:d] = np.asarray(m.position[:d])
        if d == 3 and 2 not in m.axes:  # height not measured: start on the grid's middle
            x[2] = self.plane_z
        P[:d, :d] = np.diag(np.full(d, 4.0))  # unmeasured axes: +-2 m, the scale of a room
        P[np.ix_(m.axes, m.axes)] = m.R
        P[d:, d:] = self.motion.initial_speed_sigma ** 2 * np.eye(d)
        track = Track(next(self._ids), x, P, self.plane_z, t_s=t,
                      history=deque(maxlen=self.max_history),
                      steps=deque(maxlen=self.max_history))
        if self.confirm[0] <= 1:
            track.status = "confirmed"
        self._remember(track, True)
        return track


def _check_options(max_tracks, gate_probability, fallback_sigma_m, min_sigma_m, confirm,
                   max_misses, frame_interval_s, max_sigma_m, max_birge_ratio):
    def positive(v, name, example, integer=False):
        ok = isinstance(v, (int, np.integer)) if integer else isinstance(v, (int, float))
        require(ok and not isinstance(v, bool) and math.isfinite(v) and v > 0, name,
                f"must be a positive {'integer' if integer else 'number'}, got {v!r}",
                f"pass e.g. {example}")
    positive(max_tracks, "max_tracks", 1, integer=True)
    positive(fallback_sigma_m, "fallback_sigma_m", 0.05)
    positive(min_sigma_m, "min_sigma_m", 0.002)
    positive(max_misses, "max_misses", 5, integer=True)
    positive(frame_interval_s, "frame_interval_s", 0.1)
    if max_sigma_m is not None:
        positive(max_sigma_m, "max_sigma_m", 0.5)
    if max_birge_ratio is not None:
        positive(max_birge_ratio, "max_birge_ratio", 2.0)
    require(isinstance(gate_probability, float) and 0 < gate_probability < 1,
            "gate_probability", f"must be in (0, 1), got {gate_probability!r}", "pass 0.999")
    require(isinstance(confirm, (tuple, list)) and len(confirm) == 2
            and all(isinstance(v, int) and v >= 1 for v in confirm) and confirm[0] <= confirm[1],
            "confirm", f"must be (M, N) with 1 <= M <= N, got {confirm!r}", "pass (2, 3)")
