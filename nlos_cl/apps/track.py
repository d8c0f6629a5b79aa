"""`nlos-cl track SEQUENCE.h5 [--json] [--video out.gif|mp4]`: follow hidden targets through a
sequence file (nlos_cl/tracking/sequence.py; a plain y-tal capture is one frame).

Frames are read one at a time; each goes through (background removal) -> Gauss filter ->
locate -> Kalman tracker (nlos_cl.tracking.Tracker). Positions, velocities and covariances are
reported in the file's own frame (as `nlos-cl locate`): `--json` prints one object per frame,
{"frame", "t_s", "tracks": [{"id", "status", "position", "velocity", "covariance"}],
"measurements": [positions]}. A progress bar goes to stderr. `--video` draws the tracks (2-sigma
error ellipses, trails) and the raw measurements over the search region, frame by frame.
`--smooth` (offline): the JSON lines come after the last frame, each track's position, velocity
and covariance smoothed with the frames after it as well (Rauch-Tung-Striebel, Tracker.smooth),
with "smoothed": true; the video and the summary stay causal (the filter's).
"""
from __future__ import annotations

import copy
import json
import sys


def _tracker(args, seq, backend):
    from ..capture import read_capture
    from ..frames import default_region, region_step
    from ..tracking import BackgroundRemover, ConstantVelocity, Tracker
    first = seq[0].histograms
    h_s = args.h_ns * 1e-9
    if args.region is None:
        grid = default_region(first, h_s)
    else:
        a0, a1, b0, b1, c0, c1 = args.region
        step = args.step if args.step is not None else region_step(first, h_s)
        grid = seq.frame.grid(((a0, a1), (b0, b1), (c0, c1)), step)
    background = None
    if args.background:
        background = BackgroundRemover(read_capture(args.background)[0], backend=backend)
    elif args.running_mean is not None:
        background = BackgroundRemover(alpha=args.running_mean, backend=backend)
    estimator = "paper"
    if args.estimator == "model":
        from ..model import ModelEstimator
        estimator = ModelEstimator(targets=args.targets)
    interval = 1.0 / seq.fps if seq.fps else 0.1
    return Tracker(seq, grid, estimator=estimator, h_s=h_s, background=background,
                   motion=ConstantVelocity(accel_sigma=args.accel), max_tracks=args.targets,
                   frame_interval_s=interval, backend=backend)


def _entry(frame, tracks, measurements, cframe, smoothed=None) -> dict:
    """One frame's JSON object; `smoothed`: {(id, frame): Smoothed} replaces the filter's
    position, velocity and covariance where it holds the track."""
    import numpy as np

    from .files import _covariance_json
    m = np.asarray(cframe.matrix)
    r5 = lambda v: [round(float(x), 5) for x in np.ravel(v)]  # noqa: E731
    states = [(t, (smoothed or {}).get((t.id, frame.index))) for t in tracks]
    states = [(t, s.position, s.velocity, s.covariance) if s is not None else
              (t, t.position, t.velocity, t.position_covariance) for t, s in states]
    entry = {"frame": frame.index, "t_s": frame.t_s,
             "tracks": [{"id": t.id, "status": t.status,
                         "position": r5(cframe.from_internal(p)),
                         "velocity": r5(cframe.from_internal(v)),
                         "covariance": _covariance_json(c, m)} for t, p, v, c in states],
             "measurements": [r5(cframe.from_internal(x.position)) for x in measurements],
             "truths": None if frame.truths is None else
             [r5(cframe.from_internal(p)) for p in frame.truths]}
    if smoothed is not None:
        entry["smoothed"] = True
    return entry


def main(args) -> int:
    from tqdm import tqdm

    from ..backend import resolve_backend
    from ..tracking import read_sequence
    seq = read_sequence(args.file)
    backend = resolve_backend(args.device)
    if args.video:
        _check_video_path(args)
    tracker = _tracker(args, seq, backend)
    stop = len(seq) if args.max_frames is None else min(args.max_frames, len(seq))
    smooth = args.smooth
    drawn, kept = [], []
    bar = tqdm(total=stop, unit="frame", desc="track", file=sys.stderr,
               disable=args.no_progress)
    for frame in seq.frames(0, stop):
        tracks = tracker.update(frame.histograms, frame.t_s)
        if args.json and smooth:  # small: the frame's header, tracks and measurements
            kept.append((frame, [copy.copy(t) for t in tracks], tracker.last_measurements))
        elif args.json:
            print(json.dumps(_entry(frame, tracks, tracker.last_measurements, seq.frame)),
                  flush=True)
        if args.video:
            drawn.append(_drawn(frame, tracks, tracker.last_measurements))
        bar.update(1)
    bar.close()
    if kept:
        smoothed = {(tid, s.frame): s for tid, points in tracker.smooth().items()
                    for s in points}
        for frame, tracks, measurements in kept:
            print(json.dumps(_entry(frame, tracks, measurements, seq.frame, smoothed)))
    if not args.json:
        for t in tracker.tracks:
            where = [round(float(v), 3) for v in seq.frame.from_internal(t.position)]
            print(f"track {t.id} ({t.status}): at {where} m in the file's frame "
                  f"({seq.frame.name}), {len(t.history)} frames")
    if args.video:
        _video(args, drawn, tracker.grid)
    return 0


def _drawn(frame, tracks, measurements):
    """What one video frame needs (our frame, x/y plane): small, kept for the whole video."""
    return (frame.index, frame.t_s,
            [(t.id, t.position[:2].copy(), t.covariance[:2, :2].copy(),
              [(h[2], h[3]) for h in list(t.history)[-30:]]) for t in tracks],
            [m.position[:2].copy() for m in measurements],
            None if frame.truths is None else frame.truths[:, :2].copy())


def _check_video_path(args) -> None:
    from pathlib import Path

    from ..errors import require
    path = Path(args.video)
    require(path.suffix in (".gif", ".mp4"), "--video", f"{path} is neither .gif nor .mp4",
            "pass e.g. tracks.gif")
    require(path.parent.is_dir(), "--video", f"the folder {path.parent} does not exist",
            "pass a path in an existing folder")
    require(args.force or not path.exists(), "--video", f"{path} exists",
            "pick another path, or pass --force to replace it")


def _video(args, drawn, grid) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from matplotlib import animation

    from ..safe_io import atomic_write
    x, y, _ = grid.axes()
    fig, ax = plt.subplots(figsize=(5, 5))

    def draw(i):
        index, t, tracks, meas, truths = drawn[i]
        ax.clear()
        ax.set(xlim=(x[0], x[-1]), ylim=(y[0], y[-1]), xlabel="x (m)", ylabel="y (m, from the "
               "wall)", title=f"frame {index}, t = {t:.2f} s")
        if truths is not None:
            ax.plot(truths[:, 0], truths[:, 1], "k+", ms=10, label="truth")
        for m in meas:
            ax.plot(*m, "rx", ms=6)
        for tid, p, cov, trail in tracks:
            trail = np.array(trail)
            ax.plot(trail[:, 0], trail[:, 1], "-", lw=1)
            w, v = np.linalg.eigh(cov)
            ang = np.linspace(0, 2 * np.pi, 60)
            ell = (v @ (2 * np.sqrt(np.maximum(w, 0))[:, None] * [np.cos(ang), np.sin(ang)]))
            ax.plot(p[0] + ell[0], p[1] + ell[1], "b-", lw=1)
            ax.annotate(str(tid), p, color="b")
    anim = animation.FuncAnimation(fig, draw, frames=len(drawn))
    suffix = ".gif" if args.video.endswith(".gif") else ".mp4"
    writer = animation.PillowWriter(fps=10) if suffix == ".gif" else animation.FFMpegWriter(fps=10)

    def write(tmp):  # the writers pick the format by suffix: save beside, then move in
        import os
        named = f"{tmp}{suffix}"
        try:
            anim.save(named, writer=writer)
            os.replace(named, tmp)
        finally:
            if os.path.exists(named):
                os.unlink(named)
    atomic_write(args.video, write, force=True, what="--video", kind="a video")
    plt.close(fig)
