"""`Tracker`: hidden targets followed over frames, with identities; a short composition of the
roles next to it: motion (constant-velocity models, one or an IMM of two), kalman (predict,
update, gate, smooth), association (screening, gating, assignment), lifecycle (births, confirmation,
deletion, the record), warm (the prior that starts a model fit from the predictions), track.

Per frame: every live track is predicted to the frame's time, once -> (background removal) ->
nl.GaussFilter -> nl.Locator (plans built once; the warm prior from the predictions) -> the
estimator's targets become measurements (nlos_cl.tracking.kalman.measurement) -> measurements are
screened and paired with tracks (nlos_cl.tracking.association: vague, misfit and duplicate fits
out; SciPy's linear_sum_assignment on the squared Mahalanobis distance inside a chi-square gate;
one blob for two tracks updates neither) -> paired tracks are updated, the others coast on
their prediction -> measurements left over start tentative tracks (while fewer than
`max_tracks` are alive). A tentative track is confirmed after M hits in its first N frames
(`rules=TrackRules(confirm=(M, N))`) and deleted if it is not; a confirmed track is deleted after `max_misses`
frames in a row without a measurement. Identities survive crossings because the assignment
compares measurements with each track's *predicted* position and covariance, and tracks coast
where the measurements cannot tell the targets apart. A target whose track lost it while every
slot is taken (`reacquire=True`, nlos_cl.tracking.recovery) is re-found by free measurements
with a birth's M-of-N evidence and continues that track, under its id, where the track could
have reached it at a birth's speed prior. `smooth()`: the offline RTS smoother over every
track's record.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from ..core.errors import InputError, refuse_moved, require
from ..core.tuning import auto_log_mode
from . import association, gated, kalman, warm
from .births import TargetCount, supported
from .lifecycle import Lifecycle
from .recovery import Recovery
from .motion import MEMBERS as MOTION_MEMBERS, Interacting
from .options import GROUPS, MeasurementNoise, SearchPlan, TrackRules
from .track import Smoothed, Track  # noqa: F401  (Smoothed: what Track.smoothed() returns)

NO_SIGNAL = "no cell has a non-zero likelihood"


class Tracker:
    """`Tracker(layout, grid, estimator='paper'|'mean'|'model'|object, motion=Interacting())`;
    `update(frame, t_s=None) -> list[Track]` (the live tracks, confirmed and tentative).

    layout: a nl.Layout or anything with `.layout` (HistogramSet, Signals, a read Sequence).
    frame: a HistogramSet (uploaded) or Signals, unfiltered. t_s: the frame's time (default:
    the previous one + frame_interval_s). background: a BackgroundRemover or None. max_tracks:
    how many targets may be followed at once (the model estimator finds several with
    estimator=ModelEstimator(targets=K)). noise, rules, plan: the option groups of
    tracking.options (MeasurementNoise, TrackRules, SearchPlan: plan.warm_start fits each frame
    from the confirmed tracks' last plates moved to their predictions, ~10x faster;
    plan.gated_search searches near the tracks where that can do). See the module docstring."""

    def __init__(self, layout, grid=None, *, estimator="paper", motion=None,
                 h_s: float | None = None, background=None, max_tracks: int = 1,
                 frame_interval_s: float = 0.1, backend=None,
                 noise: MeasurementNoise = MeasurementNoise(), rules: TrackRules = TrackRules(),
                 plan: SearchPlan = SearchPlan(), **moved):
        refuse_moved("Tracker", moved, GROUPS, "estimator, motion, h_s, background, max_tracks, "
                     "frame_interval_s, backend, noise, rules or plan (tracking.options)")
        from ..core.grid import Grid
        from ..localization.estimators import as_estimator
        from ..localization.filter import GaussFilter
        from ..localization.locator import Locator
        layout = getattr(layout, "layout", layout)
        grid = Grid() if grid is None else grid
        motion = Interacting() if motion is None else motion
        require(all(hasattr(motion, m) for m in MOTION_MEMBERS), "motion", f"expected a motion "
                f"model ({', '.join(MOTION_MEMBERS)}), got {type(motion).__name__}",
                "pass Interacting() or ConstantVelocity(accel_sigma=0.5)")
        _check_options(max_tracks, rules.gate_probability, noise.fallback_sigma_m,
                       noise.min_sigma_m, rules.max_misses, frame_interval_s, noise.max_sigma_m,
                       noise.max_birge_ratio)
        log_mode = auto_log_mode(layout.n_detectors) if plan.log_mode is None else \
            bool(plan.log_mode)
        self.gauss = GaussFilter(h_s, layout.time_axis, backend=backend)
        self.estimator = as_estimator(estimator)
        # targets='auto': how many to fit is chosen per frame (tracking.births)
        self.count = TargetCount(max_tracks) \
            if getattr(self.estimator, "targets", None) == "auto" else None
        self.warm_start = bool(plan.warm_start) and warm.can_start(self.estimator, fixed=True)
        self.locator = Locator(layout, grid, estimator=self.estimator, log_mode=log_mode,
                               backend=backend, search=plan.search)
        self.layout, self.grid, self.motion, self.background = layout, grid, motion, background
        self.dims = motion.dims or (3 if grid.shape[2] > 1 else 2)
        self.plane_z = float(grid.origin[2] + 0.5 * (grid.shape[2] - 1) * grid.step[2])
        self.lifecycle = Lifecycle(motion, self.dims, self.plane_z, confirm=rules.confirm,
                                   max_misses=rules.max_misses, max_history=rules.max_history)
        self.max_tracks, self.gate_probability = int(max_tracks), float(rules.gate_probability)
        # the targets this frame may hold: the gated box's count, and where every slot is
        # taken a free measurement is a lost target re-found (recovery), not a birth
        self.slots = self.max_tracks
        self.recovery = Recovery(self.lifecycle, motion, self.gate_probability) \
            if rules.reacquire else None
        self.frame_interval_s, self.backend = float(frame_interval_s), backend
        self.gated_search = bool(plan.gated_search)
        self.fallback_sigma_m = float(noise.fallback_sigma_m)
        self.max_sigma_m, self.max_birge_ratio = noise.max_sigma_m, noise.max_birge_ratio
        self._as_measurement = functools.partial(
            kalman.measurement, d=self.dims, fallback_sigma_m=self.fallback_sigma_m,
            min_sigma_m=float(noise.min_sigma_m),
            unseen_axis=_unseen_axis(layout))
        self.counted_fit = False  # this frame fitted as many targets as the tracks' plates
        # the wall spots' centroid: a closed object's centre lies away from it (tracking.depth)
        self.wall = np.vstack([np.reshape(layout.laser_spot, (-1, 3)),
                               layout.detector_spots]).mean(axis=0)
        self.tracks: list[Track] = []  # live
        self.finished: list[Track] = []  # deleted, most recent last (at most 100 kept)
        self.frame_index, self.t_s = -1, None
        # the last frame's Location, measurements and filtered Signals (a display's joint map)
        self.last_location, self.last_measurements, self.last_filtered = None, [], None

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
        t = _next_time(self.t_s, t_s, self.frame_interval_s)
        # once per frame: the warm prior and the filter share the predictions
        predictions = kalman.predict_tracks(self.tracks, t, self.motion)
        return self._advance(self._measure(frame, predictions), t, predictions)

    def step(self, measurements, t_s: float | None = None) -> list[Track]:
        """Advance the tracks with given measurements: kalman.Measurements or LocatedTargets
        (positions with or without covariance), e.g. from another localization pipeline."""
        t = _next_time(self.t_s, t_s, self.frame_interval_s)
        measurements = [m if isinstance(m, kalman.Measurement) else self._as_measurement(m)
                        for m in measurements]
        return self._advance(measurements, t, kalman.predict_tracks(self.tracks, t, self.motion))

    def measure(self, frame, t_s: float | None = None) -> list:
        """The frame's located targets as Kalman measurements ([] if it holds no signal).
        t_s: the frame's time; with it the model estimator is warm-started from the confirmed
        tracks' predictions (nlos_cl.tracking.warm). The tracks are not advanced."""
        predictions = None if t_s is None else kalman.predict_tracks(self.tracks, float(t_s),
                                                                     self.motion)
        return self._measure(frame, predictions)

    # ------------------------------------------------------------------ the roles, composed
    def _measure(self, frame, predictions) -> list:
        from ..ops.signals import as_signals
        sig = as_signals(frame, self.backend)
        if self.background is not None:
            sig = self.background(sig)
            if getattr(self.background, "alpha", 0) > 0 and self.background.frames_seen == 1:
                self.last_location, self.last_measurements, self.last_filtered = None, [], None
                return []  # a running mean's first frame: nothing learnt to subtract yet
        if self.count is not None:
            targets, most = self.count.for_frame(self.tracks)
            self.estimator.targets, self.estimator.max_targets = targets, most
            self.slots = most
        fixed = isinstance(getattr(self.estimator, "targets", 1), int)
        self.counted_fit = fixed  # the tracks' own plates fitted: no 'auto' (association)
        starters = warm.starters(predictions, self.estimator.targets, self.count is not None) \
            if self.warm_start and fixed and predictions is not None else None
        box = gated.search_box(self, predictions)  # None: the whole region
        location, found = self._locate(sig, starters and warm.prior(starters), box)
        if starters is not None and \
                warm.outside_gates(found, starters, self.gate_probability, self.wall):
            location, found = warm.better((location, found), self._recheck(sig, starters))
        if self.count is not None:
            found = supported(found)
            if self.count.try_more(location, self.estimator.targets):
                location, found = self._one_more(sig, location, found)
            # as many tracks as the data hold targets now: a free measurement beyond the
            # live tracks is a birth, one among them a lost target to re-find (recovery)
            self.slots = max(1, min(self.max_tracks, association.count_objects(found)))
        self.last_location, self.last_measurements = location, found
        return found

    def _recheck(self, sig, starters):
        """The frame fitted cold over the whole region, where a warm fit landed outside every
        gate (a turn, or another basin), in the starters' family where they are all plates:
        no closed shapes. `warm.better` then compares two plate fits' costs (a closed fit's
        one more parameter would win it by the cost alone), and on docs/scenes/walk.yaml the
        closed search concluded the plate at a turn for 2.4 s of a 0.1 s-a-frame track."""
        plates = all(p.track.model == "plate" for p in starters)
        kept = getattr(self.estimator, "closed", None)
        if plates and kept == "auto":
            self.estimator.closed = False
        try:
            return self._locate(sig, None)
        finally:
            if plates and kept == "auto":
                self.estimator.closed = kept

    def _one_more(self, sig, location, found):
        """The frame fitted again cold over the whole region with 'auto', up to one target
        more than `found` (tracking.births): kept where it found more."""
        k = self.estimator.targets
        self.estimator.targets, self.estimator.max_targets = "auto", k + 1
        try:
            again = self._locate(sig, None)
        finally:
            self.estimator.targets, self.estimator.max_targets = k, k
        more = len(again[1]) > len(found)
        self.count.tried(more)
        self.counted_fit = not more
        return again if more else (location, found)

    def _locate(self, sig, prior, within=None):
        """(Location or None, measurements), from `prior`, the argmax `within` a box, if given."""
        try:
            self.last_filtered = self.gauss(sig)
            births = sum(t.status == "confirmed" for t in self.tracks) < self.max_tracks
            location = self.locator(self.last_filtered, raw=sig, prior=prior, detect=births,
                                    within=within)
        except InputError as exc:
            if NO_SIGNAL not in str(exc):
                raise
            location = None
        return location, [self._as_measurement(tg) for tg in getattr(location, "targets", [])]

    def _advance(self, measurements, t: float, predictions) -> list[Track]:
        """Apply the predictions, pair the measurements, update, count, bury and give birth."""
        self.frame_index += 1
        for prediction in predictions:
            kalman.apply_prediction(prediction, t)
        given = measurements
        measurements = association.screen(
            measurements, max_sigma_m=self.max_sigma_m, max_birge_ratio=self.max_birge_ratio,
            gate_probability=self.gate_probability)
        pairs, free = association.associate(self.tracks, measurements, self.gate_probability,
                                                 self.wall)
        extras = {}
        # one object, one track; not where K is given (K targets), nor while a live track
        # missed (a free plate touching another's may be its target, to re-find: recovery)
        if self.count is not None and len(pairs) == len(self.tracks):
            carried = [tr for tr, _ in pairs if tr.extra] if self.counted_fit else []
            kept = {id(m.source) for m in measurements}
            free, extras = association.objects(
                pairs, free, carried, [m for m in given if id(m.source) not in kept])
        for track, m in pairs:
            kalman.update_track(track, m)
            warm.remember(track, m, extras.get(id(m), ()))
        paired = {id(tr) for tr, _ in pairs}
        if self.recovery is not None:  # a lost target re-found continues its track
            recovered, free = self.recovery.step(self.tracks, paired, free, t, self.frame_index,
                                                 len(self.tracks) >= self.slots)
            paired |= recovered
        _bury_and_bear(self, paired, free, t, extras)
        self.t_s = t
        return list(self.tracks)


def _bury_and_bear(tracker, paired: set, free: list, t: float, extras: dict) -> None:
    """Count each track's hit or miss (deleting where due), then births from `free` (each with
    its object's other plates, `extras`)."""
    for track in list(tracker.tracks):
        if tracker.lifecycle.account(track, id(track) in paired, tracker.frame_index):
            tracker.tracks.remove(track)
            tracker.finished = (tracker.finished + [track])[-100:]
    for m in free:
        if len(tracker.tracks) < tracker.slots:
            born = tracker.lifecycle.birth(m, t, tracker.frame_index)
            warm.keep(born, m, extras.get(id(m), ()))  # a counting tracker warm-starts it
            tracker.tracks.append(born)

def _next_time(previous, t_s, interval):
    """The frame's time: t_s, checked to come after the previous frame's, or one interval on."""
    if t_s is None:
        return 0.0 if previous is None else previous + interval
    require(isinstance(t_s, (int, float, np.floating)) and math.isfinite(float(t_s))
            and (previous is None or float(t_s) > previous), "t_s",
            f"must be a finite time after the previous frame's ({previous}), got {t_s!r}",
            "pass increasing frame timestamps in seconds")
    return float(t_s)


def _check_options(max_tracks, gate_probability, fallback_sigma_m, min_sigma_m, max_misses,
                   frame_interval_s, max_sigma_m, max_birge_ratio):
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


def _unseen_axis(layout) -> int | None:
    """The axis the layout's wall spots cannot see (z for a line along x, x for one along z:
    region.unseen_axis, the rule the search region and the model fit hold it by), never
    measured; None where they see all three."""
    from ..localization.region import unseen_axis
    return unseen_axis(np.vstack([np.reshape(layout.laser_spot, (-1, 3)),
                                  layout.detector_spots]))
