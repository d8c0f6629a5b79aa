"""`nlos-cl track SEQUENCE.h5 [--json] [--csv FILE.csv] [--video out.gif|mp4]`: follow hidden
targets through a sequence file (a plain y-tal capture is one frame), with the library's
track_sequence (nlos_cl/tracking/sequences.py).

Frames are read one at a time; each goes through (background removal) -> Gauss filter ->
locate -> Kalman tracker (nlos_cl.tracking.Tracker). Everything is in the file's own frame (as
`nlos-cl locate`): each frame prints a line per track (position ± 1 sd per axis), or with
`--json` one object {"frame", "t_s", "tracks": [{"id", "status", "position", "velocity",
"covariance"}], "measurements": [positions], "truths", "detected"}; `--csv` keeps the same as a
table (apps/track_output.py). A progress bar goes to stderr. `--video` writes an animation of
the joint map with the tracks while tracking (apps/track_video.py). Exit status 3 (as locate's)
where no frame held target signal.
`--smooth` (offline): the lines come after the last frame, each track's position, velocity
and covariance smoothed with the frames after it as well (Rauch-Tung-Striebel, Tracker.smooth),
with "smoothed": true; the video and the summary stay causal (the filter's). `--lag L` (real
time with a latency): frame k's line is printed after frame k + L, with each track's fixed-lag
estimate (Tracker.lagged(L): the L later frames used) and "lag_frames": L; the last L frames
get theirs at the end, from the frames there are (lag_frames L - 1, ..., 0).

A sequence of ONE confocal spot (Keyhole's scans, as `nlos-cl convert` writes them) cannot place
a target, only its range from the spot: it is tracked as a range (nlos_cl.tracking.ranges,
`_range_main`), one line per frame ({"frame", "t_s", "range_m", "range_sd_m",
"range_speed_m_s", "measured_range_m", "detected"} with --json; null where a frame has no
return: the filter coasts), with --smooth smoothed and "smoothed": true, the options that place
targets refused with a one-line reason.
"""
from __future__ import annotations

import math
import re
import sys
import warnings

from ..core.errors import warn
from .locate import NO_TARGET_STATUS


def _h_s(args) -> float | None:
    return None if args.h_ns is None else args.h_ns * 1e-9


def tracker_options(args, backend) -> dict:
    """The command's options as nlos_cl.tracking.sequences.tracker_for takes them (errors
    name the flags)."""
    from .cli_types import OPTION_FLAGS
    region = None if args.region is None else list(zip(args.region[::2], args.region[1::2]))
    return {"estimator": args.estimator, "targets": args.targets,
            "reflectance": args.reflectance, "region": region, "step_m": args.step,
            "h_s": _h_s(args), "background": args.background or None,
            "running_mean": args.running_mean, "motion": motion_model(args),
            "full_search": args.full_search, "backend": backend, "names": OPTION_FLAGS,
            "on_note": _warn}


def _warn(text: str) -> None:
    """The default estimator's note, printed as the command always has (whatever Python's
    warning filters say)."""
    print(f"nlos-cl: warning: {text}", file=sys.stderr)


def motion_model(args):
    """--motion: the IMM of a steady (--steady-accel) and a manoeuvring (--accel) mode, or one
    constant-velocity model (--accel)."""
    from ..tracking.sequences import motion_for
    from .cli_types import OPTION_FLAGS
    return motion_for(args.motion, accel=args.accel, steady_accel=args.steady_accel,
                      names=OPTION_FLAGS)


def _entry(frame, tracks, measurements, cframe, smoothed=None, mark=None) -> dict:
    """One frame's JSON object (tracking.sequences.frame_json: the library's)."""
    from ..tracking.sequences import frame_json
    return frame_json(frame, tracks, measurements, cframe, smoothed, mark)


def main(args) -> int:
    from ..core.errors import require
    from ..io.ytal.reading import read_sequence
    from ..ops.backend import resolve_backend
    require(not (args.lag and args.smooth), "--lag", "prints fixed-lag lines, and --smooth "
            "already uses every later frame", "pass --lag N without --smooth")
    if args.csv:
        from .track_output import check_csv_path
        check_csv_path(args)
    seq = read_sequence(args.file)
    backend = resolve_backend(args.device)
    from ..localization.ranges import is_single_confocal
    if is_single_confocal(seq[0].histograms):
        return _range_main(args, seq, backend)
    if args.video:
        from .track_video import check_video_path
        check_video_path(args)
    from ..tracking.sequences import track_sequence
    run = track_sequence(seq, max_frames=args.max_frames, progress=not args.no_progress,
                         **tracker_options(args, backend))
    detected = _written(args, seq.frame, lambda video, out: _loop(args, run, video, out),
                        video_of=args.video and (lambda path, tmp: _video(path, tmp, run)))
    if not args.json:
        from ..tracking.static import holds_still
        for t in run.tracker.tracks:
            where = [round(float(v), 3) for v in seq.frame.from_internal(t.position)]
            still = ", static: furniture or a target standing still" if holds_still(t) else ""
            print(f"track {t.id} ({t.status}{still}): at {where} m in the file's frame "
                  f"({seq.frame.name}), {len(t.history)} frames")
    return _status(detected, len(run))


def _status(detected: int, frames: int) -> int:
    """0, or 3 (as `nlos-cl locate`) where no frame held target signal."""
    if detected:
        return 0
    print(f"nlos-cl: no target signal in any of the {frames} frames", file=sys.stderr)
    return NO_TARGET_STATUS


def _written(args, frame, body, video_of=None, ranges: bool = False):
    """body(video, outputs) inside the temporaries of --video (video_of(path, tmp): the Video)
    and --csv (a range track's columns with `ranges`): each file is moved in only when the
    whole run is complete (an interrupted run leaves no partial file). Returns body's value."""
    from ..io.safe_write import atomic_write
    from .track_output import Outputs
    done = []

    def with_csv(video):
        if not args.csv:
            return body(video, Outputs(args.json, frame.axes, ranges=ranges))

        def write(tmp):
            with open(tmp, "w", newline="") as fh:
                done.append(body(video, Outputs(args.json, frame.axes, fh, ranges)))
        atomic_write(args.csv, write, force=args.force, what="--csv", kind="a track table")
        return done[-1]
    if not video_of:
        return with_csv(None)

    def write(tmp):
        with video_of(args.video, tmp) as video:
            done.append(with_csv(video))
    # the same rule as check_video_path, applied again now that the video is complete
    atomic_write(args.video, write, force=args.force, what="--video", kind="a video")
    return done[-1]


def _video(path, tmp, run):
    from .track_video import Video
    return Video(path, tmp, run.tracker, run.sequence.frame)


# what places targets, which one confocal spot cannot do: (flag, set?) for `_range_main`
RANGE_REFUSED = (("--video", lambda a: a.video), ("--estimator", lambda a: a.estimator),
                 ("--targets", lambda a: a.targets not in (1, "auto")), ("--region", lambda a: a.region),
                 ("--step", lambda a: a.step), ("--reflectance", lambda a: a.reflectance),
                 ("--background", lambda a: a.background),
                 ("--running-mean", lambda a: a.running_mean is not None),
                 ("--full-search", lambda a: a.full_search), ("--lag", lambda a: a.lag))


def _range_main(args, seq, backend) -> int:
    """One confocal spot: the range per frame (localization.ranges), tracked by
    tracking.ranges with --motion's models; a line per frame (JSON with --json; --csv rows),
    and a summary in text; exit 3 where no frame holds a return."""
    from tqdm import tqdm

    from ..core.errors import require
    from ..tracking.ranges import frame_ranges, track_steps
    for flag, given in RANGE_REFUSED:
        require(not given(args), flag, "does not apply to a sequence of one confocal spot, "
                "which gives a range, not a position", f"leave out {flag}")
    stop = len(seq) if args.max_frames is None else min(args.max_frames, len(seq))
    frames = tqdm(seq.frames(0, stop), total=stop, unit="frame", desc="range",
                  file=sys.stderr, disable=args.no_progress)
    # each frame's warnings named with its frame, as the tracks' (frame_warnings)
    steps = frame_warnings(frame_ranges(frames, _h_s(args), backend=backend))
    points, sigma = track_steps(steps, motion=motion_model(args), smooth=args.smooth)
    if not points:  # no frame with a return: each frame says so
        points = [_no_range(k, f.t_s) for k, f in enumerate(seq.frames(0, stop))]

    def emit(video, out):
        for p in points:
            entry = {"frame": p.frame, "t_s": p.t_s, "range_m": _number(p.range_m),
                     "range_sd_m": _number(p.range_sd_m),
                     "range_speed_m_s": _number(p.speed_m_s),
                     "measured_range_m": _number(p.measured_m),
                     "detected": math.isfinite(p.measured_m)}
            out.range(entry | ({"smoothed": True} if args.smooth else {}))
        return sum(math.isfinite(p.measured_m) for p in points)
    detected = _written(args, seq.frame, emit, ranges=True)
    if not args.json and detected:
        spot = [round(float(v), 3)
                for v in seq.frame.from_internal(seq[0].histograms.laser_spots[0])]
        last = next(p for p in reversed(points) if math.isfinite(p.range_m))
        print(f"range track of the confocal spot at {spot} m in the file's frame "
              f"({seq.frame.name}): {len(points)} frames, {detected} with a return, last "
              f"range {last.range_m:.4f} m (sd {last.range_sd_m:.4f}), measurement sd "
              f"{sigma:.4f} m")
    return _status(detected, len(points))


def _no_range(k, t_s):
    from ..tracking.ranges import RangePoint
    nan = float("nan")
    return RangePoint(k, t_s, nan, nan, nan, nan)


def _number(v: float):
    """A JSON number, or null where there is none (NaN)."""
    return v if math.isfinite(v) else None


def _loop(args, run, video, out) -> int:
    """Track the run's frames, each frame's entry to `out` (track_output.Outputs) as it comes
    (with --lag L, L frames later; with --smooth, every frame's after the last, smoothed), a
    video frame each. Returns how many frames held target signal."""
    from collections import deque
    kept, lag, cframe, detected = [], args.lag or 0, run.sequence.frame, 0
    recent = deque(maxlen=lag + 1)  # --lag: the frames whose lines wait for later frames
    for step in frame_warnings(run):
        header = (step.frame, step.tracks, step.measurements)
        detected += bool(step.measurements)
        if args.smooth:
            kept.append(header)
        elif lag:
            recent.append(header)
            if len(recent) > lag:
                _lagged(out, recent[0], run.tracker.lagged(lag), lag, cframe)
        else:
            out.frame(_entry(*header, cframe))
        if video is not None:
            video.add(*header)
    waiting = list(recent)[1:] if len(recent) > lag else list(recent)
    for i, header in enumerate(waiting):  # the last frames: as many later frames as there are
        after = len(waiting) - 1 - i
        _lagged(out, header, run.tracker.lagged(after), after, cframe)
    if kept:
        smoothed = {(tid, s.frame): s for tid, points in run.tracker.smooth().items()
                    for s in points}
        for header in kept:
            out.frame(_entry(*header, cframe, smoothed, {"smoothed": True}))
    return detected


def _lagged(out, header, lagged, lag, cframe) -> None:
    """A frame's entry with its tracks' fixed-lag estimates ({id: Smoothed}, Tracker.lagged)."""
    smoothed = {(tid, s.frame): s for tid, s in lagged.items()}
    out.frame(_entry(*header, cframe, smoothed, {"lag_frames": lag}))


def frame_warnings(run):
    """The run's steps (anything with a `frame` that has `index` and `t_s`: a tracking run's,
    or a range track's frame_ranges), each frame's warnings (the estimator's, NumPy's) said
    again naming the frame they come from: a text the first time with its frame's number and
    time, and after the last frame once more with the later frames that gave it too (a text
    that differs only in its numbers, a Birge ratio per frame, is the same warning)."""
    steps, later = iter(run), {}
    while True:
        step = None
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")  # every frame's, not once per code line
                step = next(steps, None)
        finally:  # an error ends the run: its frame's warnings are still said
            _attribute(caught, step, later)
        if step is None:
            break
        yield step
    for first, category, frames, differ in later.values():
        if frames:
            how = "again, with each frame's own numbers" if differ else "again"
            warn(f"{first} ({how}: {_frames(frames)})", category)


NUMBER = re.compile(r"[-+]?\d+(?:[.,]\d+)*(?:e[-+]?\d+)?")


def _attribute(caught, step, later: dict) -> None:
    """Say each caught warning with its frame the first time; after that, keep the frame under
    the warning's text with its numbers left out."""
    for w in caught:
        text = " ".join(str(w.message).split())
        key = NUMBER.sub("#", text)
        if step is None:  # not a frame's (the run's end, or an error)
            warn(text, w.category)
        elif key in later:
            first, category, frames, differ = later[key]
            if not frames or frames[-1].index != step.frame.index:  # once a frame
                frames.append(step.frame)
            later[key] = (first, category, frames, differ or text != first)
        else:
            later[key] = (text, w.category, [], False)
            warn(f"frame {step.frame.index} (t {step.frame.t_s:.3f} s): {text}", w.category)


def _frames(frames) -> str:
    """'frame 4, t 0.400 s', or 'frames 4-6, 9, t 0.400 .. 0.900 s'."""
    if len(frames) == 1:
        return f"frame {frames[0].index}, t {frames[0].t_s:.3f} s"
    runs = []
    for n in (f.index for f in frames):
        if runs and n == runs[-1][1] + 1:
            runs[-1][1] = n
        else:
            runs.append([n, n])
    spans = ", ".join(f"{a}" if a == b else f"{a}-{b}" for a, b in runs)
    return f"frames {spans}, t {frames[0].t_s:.3f} .. {frames[-1].t_s:.3f} s"
