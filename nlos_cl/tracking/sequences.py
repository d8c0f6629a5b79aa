"""Track a sequence: the library's one way to build a Tracker for a sequence file (or an opened
Sequence) with the defaults `nlos-cl track` uses, and to run it frame by frame.

    for step in nl.track_sequence("walk.h5"):
        print(step.frame.index, step.positions)     # the file's frame (y-tal's X, Y, Z)

    run = nl.track_sequence("walk.h5", targets=2, max_frames=50)
    steps = list(run)                 # every frame's tracks and measurements
    smoothed = run.tracker.smooth()   # offline: Rauch-Tung-Striebel over the frames run

Each step's `positions`, `covariances` and `as_json()` are in the file's own frame (as
`nlos-cl track` prints them); its `tracks` and `measurements` are the Tracker's objects, in
ours (`run.sequence.frame.from_internal` converts). A sequence of one confocal spot gives a range per frame, not a position:
nlos_cl.tracking.ranges.track_frames follows it.
"""
from __future__ import annotations

import copy
import sys
import warnings
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Iterator, Mapping

import numpy as np

from ..core.errors import require, spelled
from ..core.stats import unique_sorted
from ..localization.estimators import choose_estimator
from .motion import ConstantVelocity, Interacting, MotionModel
from .options import MeasurementNoise, SearchPlan
from .tracker import Tracker

# How errors name the options: the keywords here; the CLI passes its flags (OPTION_FLAGS).
OPTION_NAMES = {"region": "region", "step_m": "step_m", "estimator": "estimator",
                "targets": "targets", "reflectance": "reflectance", "accel": "accel",
                "steady_accel": "steady_accel", "motion": "motion", "background": "background"}
REACH_FRAMES = 32  # frames spread over the sequence whose signal bounds the search region


def motion_for(kind: str = "imm", *, accel: float = 0.5, steady_accel: float = 0.05,
               names: Mapping[str, str] = OPTION_NAMES) -> MotionModel:
    """'imm': the interacting multiple model of a steady (`steady_accel`) and a manoeuvring
    (`accel`) constant-velocity mode; 'cv': one constant-velocity model (`accel`), in m/s^2."""
    require(kind in ("imm", "cv"), names["motion"], f"unknown motion {kind!r}",
            "pass 'imm' or 'cv'")
    if kind == "cv":
        return ConstantVelocity(accel_sigma=accel)
    require(steady_accel < accel, names["steady_accel"], f"must be below {names['accel']} "
            f"({accel}), got {steady_accel}", f"pass e.g. {_pair(names)}, or "
            f"{spelled(names['motion'], 'cv')}")
    return Interacting(accel_sigmas=(steady_accel, accel))


def _pair(names) -> str:
    if names["accel"].startswith("--"):
        return f"{names['steady_accel']} 0.05 {names['accel']} 0.5"
    return f"{names['steady_accel']}=0.05, {names['accel']}=0.5"


def sampled_frames(seq) -> list:
    """Up to REACH_FRAMES frames spread over the sequence: the search region reaches as far as
    their signal does (a target walking away later than frame 0 stays inside)."""
    n = len(seq)
    picks = unique_sorted(np.linspace(0, n - 1, min(n, REACH_FRAMES)).astype(int))
    return [seq[int(i)].histograms for i in picks]


def tracker_for(seq, *, estimator=None, targets: int | str = "auto", reflectance=None,
                region=None,
                step_m: float | None = None, h_s: float | None = None, background=None,
                running_mean: float | None = None, motion: MotionModel | None = None,
                full_search: bool = False, backend=None,
                names: Mapping[str, str] = OPTION_NAMES, on_note=None) -> Tracker:
    """A Tracker for `seq` (an opened Sequence) on the search region `nlos-cl locate` would use
    for its first frame, reaching as far as the signal of frames spread over the sequence.

    targets: how many targets to follow, or 'auto' (the default: the model fit finds them per
    frame, up to its max_targets, births and deaths from the data: tracking.births). estimator: None (the default policy,
    localization.estimators.choose_estimator: the model fit, warm-started from the tracks; for paired and confocal captures the mean of the paper's
    likelihood with one target and its argmax with several, with a warning), a name or an
    object. region: three (low, high) ranges along the file's axes, or a Grid; step_m with it.
    background: None (default: the static returns learned from frames spread over the
    sequence, tracking.static, are subtracted from every frame), a target-free capture (path
    or HistogramSet), or 'none' (nothing subtracted); running_mean: the weight of a running
    mean of past frames subtracted instead (for streams). motion: a
    motion model (default motion_for()). full_search: search the whole region every frame.
    on_note: what says the default's note (a callable of the text; default warnings.warn)."""
    from ..localization.capture import search_region
    first, spread = seq[0].histograms, sampled_frames(seq)
    grid, _ = search_region(first, seq.frame, region, step_m, h_s,
                            names=(names["region"], names["step_m"]), reach_from=spread)
    say = on_note or (lambda text: warnings.warn(text, stacklevel=3))
    remover = _remover(background, running_mean, spread, grid, backend, names, say)
    chosen, note = choose_estimator(estimator, targets=targets, reflectance=reflectance,
                                    paired=first.paired, tracking=True, names=names)
    if note:
        say(note)
    interval = 1.0 / seq.fps if seq.fps else 0.1
    sigma = 0.05  # the Tracker's default; the paper's argmax: measured on the first frames
    if getattr(chosen, "name", None) == "paper" and remover is None:
        from .scatter import sequence_scatter
        sigma = sequence_scatter(seq, grid, h_s=h_s, backend=backend)
    counted = getattr(chosen, "targets", None) == "auto"  # births from the data (births.py)
    most = int(getattr(chosen, "max_targets", 1)) if counted else \
        targets if isinstance(targets, int) else 1
    return Tracker(seq, grid, estimator=chosen, h_s=h_s, background=remover,
                   motion=motion_for() if motion is None else motion, max_tracks=most,
                   frame_interval_s=interval, backend=backend,
                   noise=MeasurementNoise(fallback_sigma_m=sigma),
                   plan=SearchPlan(gated_search=not full_search))


def _remover(background, running_mean, spread, grid, backend, names, say):
    """What is subtracted from every frame: a target-free capture (a path or a set), a running
    mean of past frames, nothing ('none'), or by default the static returns learned from the
    sequence (tracking.static), where they hold a return (with a note saying so)."""
    from ..io.ytal.capture import read_capture
    from ..localization.background import BackgroundRemover
    from .static import learned_background
    if isinstance(background, str) and background.lower() == "none":
        return None
    if background is not None:
        if isinstance(background, (str, Path)):
            background = read_capture(background)[0]
        from ..localization.background import require_alike
        require_alike(spread[0], background)  # the time axis, spots and laser spots too
        return BackgroundRemover(background, backend=backend)
    if running_mean is not None:
        return BackgroundRemover(alpha=running_mean, backend=backend)
    # subtracted only where it holds a return a frame's detection would see: on a sequence
    # without static returns it is noise (and the wings of movers that linger), and
    # subtracting it cost the warm model fits 3-5x (walk), 40-60x (crossing draw 1) their time
    learned = learned_background(spread, grid)
    if learned is None:
        return None
    say(f"static returns (furniture, or a target that does not move) were learned from "
        f"{len(spread)} frames spread over the sequence and subtracted, so only what moves "
        f"is tracked; pass {spelled(names['background'], 'none')} to track them too")
    return BackgroundRemover(learned, backend=backend)


@dataclass(frozen=True)
class TrackedFrame:
    """One frame's result: the frame's header (its histograms dropped), copies of the tracks
    as they stood after it (ours), the measurements the estimator gave (ours), and the file's
    frame (`capture_frame`) that `positions`, `covariances` and `as_json` report in."""
    frame: object
    tracks: list
    measurements: list
    capture_frame: object = None  # io.ytal.frames.CaptureFrame; None: ours

    @property
    def _frame(self):
        from ..io.ytal.frames import INTERNAL
        return INTERNAL if self.capture_frame is None else self.capture_frame

    @property
    def positions(self) -> list:
        """Each track's position (file frame, m)."""
        return [self._frame.from_internal(t.position) for t in self.tracks]

    @property
    def covariances(self) -> list:
        """Each track's position covariance (file frame, m^2)."""
        from ..io.json_format import covariance_in
        return [covariance_in(t.position_covariance, self._frame) for t in self.tracks]

    def as_json(self, smoothed=None, mark=None) -> dict:
        """The frame as `nlos-cl track --json` prints it (frame_json)."""
        return frame_json(self.frame, self.tracks, self.measurements, self._frame, smoothed,
                          mark)


def frame_json(frame, tracks, measurements, cframe, smoothed=None, mark=None) -> dict:
    """One frame's JSON object in `cframe` (the file's frame): tracks (id, status, static (a
    confirmed track that has not moved: static.holds_still, reported apart from the movers),
    position, velocity, covariance), measurements, truths, detected. `smoothed`: {(id, frame index):
    Smoothed} replaces the filter's position, velocity and covariance where it holds the track;
    `mark`: keys added (what replaced them: {"smoothed": true} or {"lag_frames": L})."""
    from ..io.json_format import covariance_json, vector_json
    from .static import holds_still
    found = [(t, (smoothed or {}).get((t.id, frame.index))) for t in tracks]
    states = [(t, s.position, s.velocity, s.covariance) if s is not None else
              (t, t.position, t.velocity, t.position_covariance) for t, s in found]
    entry = {"frame": frame.index, "t_s": frame.t_s,
             "tracks": [{"id": t.id, "status": t.status, "static": holds_still(t),
                         "position": vector_json(p, cframe),
                         "velocity": vector_json(v, cframe, direction=True),
                         "covariance": covariance_json(c, cframe)} for t, p, v, c in states],
             "measurements": [vector_json(x.position, cframe) for x in measurements],
             "truths": None if frame.truths is None else
             [vector_json(p, cframe) for p in frame.truths],
             "detected": bool(measurements)}
    entry.update(mark or {})
    return entry


class SequenceRun:
    """A sequence and its tracker; iterating runs the tracker over frames 0..stop-1 once,
    yielding a TrackedFrame per frame (with a progress bar on stderr if `progress`)."""

    def __init__(self, sequence, tracker: Tracker, stop: int, progress: bool = False):
        self.sequence, self.tracker, self.stop, self.progress = sequence, tracker, stop, progress
        self._started = False

    def __len__(self) -> int:
        return self.stop

    def __iter__(self) -> Iterator[TrackedFrame]:
        require(not self._started, "track_sequence", "a run's frames are tracked once",
                "call track_sequence again to track the sequence anew")
        self._started = True
        from tqdm import tqdm
        bar = tqdm(total=self.stop, unit="frame", desc="track", file=sys.stderr,
                   disable=not self.progress)
        try:
            for frame in self.sequence.frames(0, self.stop):
                tracks = self.tracker.update(frame.histograms, frame.t_s)
                yield TrackedFrame(replace(frame, histograms=None),
                                   [copy.copy(t) for t in tracks],
                                   list(self.tracker.last_measurements),
                                   getattr(self.sequence, "frame", None))
                bar.update(1)
        finally:
            bar.close()


def track_sequence(source, *, max_frames: int | None = None, progress: bool = False,
                   **options) -> SequenceRun:
    """Track the targets of a sequence file (path) or an opened Sequence with `nlos-cl track`'s
    defaults; `options` are tracker_for's (estimator, targets, region, background, motion, ...).
    Returns a SequenceRun: iterate it for each frame's tracks (a TrackedFrame); its `tracker`
    holds the tracks, their histories and smooth() / lagged(L) afterwards."""
    from ..io.ytal.reading import read_sequence
    from ..localization.ranges import is_single_confocal
    seq = read_sequence(source) if isinstance(source, (str, Path)) else source
    require(hasattr(seq, "frames") and hasattr(seq, "frame"), "source", f"expected a sequence "
            f"file's path or a Sequence, got {type(source).__name__}",
            "pass a path to a .h5 sequence (nlos_cl.write_sequence writes one)")
    require(not is_single_confocal(seq[0].histograms), "source", "holds one confocal spot, which "
            "gives a range per frame, not a position",
            "follow its range with nlos_cl.tracking.ranges.track_frames")
    tracker = tracker_for(seq, **options)
    stop = len(seq) if max_frames is None else min(int(max_frames), len(seq))
    return SequenceRun(seq, tracker, stop, progress)
