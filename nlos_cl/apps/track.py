"""`nlos-cl track SEQUENCE.h5 [--json] [--video out.gif|mp4]`: follow hidden targets through a
sequence file (nlos_cl/tracking/sequence.py; a plain y-tal capture is one frame).

Frames are read one at a time; each goes through (background removal) -> Gauss filter ->
locate -> Kalman tracker (nlos_cl.tracking.Tracker). Positions, velocities and covariances are
reported in the file's own frame (as `nlos-cl locate`): `--json` prints one object per frame,
{"frame", "t_s", "tracks": [{"id", "status", "position", "velocity", "covariance"}],
"measurements": [positions]}. A progress bar goes to stderr. `--video` writes an animation
while tracking, one frame in memory at a time, that appears only when complete (`_Video`): each
frame's joint map (the Locator's scores over the whole grid, shown as `_display` says) under
the tracks (2-sigma error ellipses, trails), the measurements and the truths, in our frame's
x/y plane. It scores the whole grid once more each frame (the tracker's own search need not
score every cell), so --video costs that much extra per frame.
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
    from ..backend import resolve_backend
    from ..safe_io import atomic_write
    from ..tracking import read_sequence
    seq = read_sequence(args.file)
    backend = resolve_backend(args.device)
    if args.video:
        _check_video_path(args)
    tracker = _tracker(args, seq, backend)
    stop = len(seq) if args.max_frames is None else min(args.max_frames, len(seq))
    kept = []
    if args.video:
        def write(tmp):  # the whole run writes the temporary: moved in only when complete
            with _Video(args.video, tmp, tracker) as video:
                kept.extend(_loop(args, seq, tracker, stop, video))
        atomic_write(args.video, write, force=True, what="--video", kind="a video")
    else:
        kept = _loop(args, seq, tracker, stop, None)
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
    return 0


def _loop(args, seq, tracker, stop, video) -> list:
    """Track frames 0..stop-1: JSON lines as they come (or, with --smooth, each frame's
    header, tracks and measurements kept for after the last: returned), a video frame each."""
    from tqdm import tqdm
    kept = []
    bar = tqdm(total=stop, unit="frame", desc="track", file=sys.stderr,
               disable=args.no_progress)
    try:
        for frame in seq.frames(0, stop):
            tracks = tracker.update(frame.histograms, frame.t_s)
            if args.json and args.smooth:  # small: the frame's header, tracks, measurements
                kept.append((frame, [copy.copy(t) for t in tracks], tracker.last_measurements))
            elif args.json:
                print(json.dumps(_entry(frame, tracks, tracker.last_measurements, seq.frame)),
                      flush=True)
            if video is not None:
                video.add(frame, tracks, tracker.last_measurements, tracker)
            bar.update(1)
    finally:
        bar.close()
    return kept


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
    if path.suffix == ".mp4":  # before any tracking, not after the last frame
        from matplotlib import animation
        require(animation.writers.is_available("ffmpeg"), "--video", "an .mp4 needs ffmpeg, "
                "which is not on the PATH", "install ffmpeg, or write a .gif")


def joint_map(tracker):
    """The last frame's joint map (tracker.locator.scores of its filtered signals: the product
    over detectors of each cell's filtered signal, or the sum of their logs in log mode) as
    (ny, nx) float64, the maximum over z for a 3D grid; None where the frame had no filtered
    signals (a running mean's first frame)."""
    sig = tracker.last_filtered
    if sig is None:
        return None
    nx, ny, nz = tracker.grid.shape
    scores = sig.backend.to_numpy(tracker.locator.scores(sig)).reshape(nz, ny, nx)
    return scores.max(axis=0)


def _display(scores, log_mode: bool, n_detectors: int):
    """A joint map for the eye, in [0, 1]: the geometric mean over detectors of the normalised
    likelihood, over its frame's peak (product ** (1/N), or exp(log sum / N) in log mode; the
    same picture either way). A product of N peaked factors is a lone spot: its N-th root keeps
    the spot brightest but shows its spread and the other near-intersections too, and a frame's
    own peak fixes the scale whatever the signal's strength. Zeros where there is no map."""
    import numpy as np
    if scores is None:
        return None
    top = float(scores.max())
    if log_mode:
        return np.exp((scores - top) / n_detectors) if top > float(scores.min()) else \
            np.zeros_like(scores)
    return (np.maximum(scores, 0.0) / top) ** (1.0 / n_detectors) if top > 0 else \
        np.zeros_like(scores)


class _Video:
    """`with _Video(path, tmp, tracker) as v: v.add(frame, tracks, measurements, tracker)` per
    frame: each frame drawn and written as it comes (nothing kept per frame), into `tmp`
    (atomic_write's temporary). An .mp4 goes through ffmpeg, which picks the format by suffix:
    written beside as tmp.mp4, moved onto tmp by close(); an exception removes it."""

    FPS, DPI = 10, 100

    def __init__(self, path: str, tmp: str, tracker):
        from ..plotting import pyplot
        self.grid, self.log_mode = tracker.grid, tracker.locator.log_mode
        self.n_detectors = tracker.layout.n_detectors
        self.tmp, self.named = tmp, (f"{tmp}.mp4" if path.endswith(".mp4") else None)
        self.plt = pyplot()
        self.fig, self.ax = self.plt.subplots(figsize=(6, 5), dpi=self.DPI,
                                              layout="constrained")
        self.image, self.overlay = self._axes(), []
        self.fig.draw_without_rendering()  # lay out once for every frame (was 1/3 of a frame)
        self.fig.set_layout_engine("none")
        if self.named is None:
            self.writer = _GifWriter(fps=self.FPS)
        else:
            from matplotlib import animation
            self.writer = animation.FFMpegWriter(fps=self.FPS)
        self._saving = None

    def __enter__(self):
        saving = self.writer.saving(self.fig, self.named or self.tmp, self.DPI)
        try:
            saving.__enter__()  # ffmpeg starts, or the GIF opens
        except BaseException:
            self.plt.close(self.fig)
            raise
        self._saving = saving
        return self

    def __exit__(self, *exc):
        import os
        try:
            if self._saving is not None:
                saving, self._saving = self._saving, None
                saving.__exit__(*exc)  # the writer's finish(): ffmpeg ends, the GIF's trailer
            if exc[0] is None and self.named is not None:
                os.replace(self.named, self.tmp)
        finally:
            if self.named is not None and os.path.exists(self.named):
                os.unlink(self.named)
            self.plt.close(self.fig)
        return False

    def close(self):
        self.__exit__(None, None, None)

    def add(self, frame, tracks, measurements, tracker) -> None:
        """Draw this frame (the tracker's last: its joint map) and write it to the video."""
        self.draw(frame, tracks, measurements, joint_map(tracker))
        self.writer.grab_frame()

    def _axes(self):
        """The map's image (updated per frame), colour bar, labels and legend."""
        import numpy as np
        from matplotlib import patheffects
        from matplotlib.lines import Line2D
        (x, y, _), (sx, sy, _) = self.grid.axes(), self.grid.step
        image = self.ax.imshow(np.zeros(self.grid.shape[1::-1]), origin="lower", cmap="magma",
                               vmin=0.0, vmax=1.0, aspect="equal",  # (fine grids: smoothed)
                               extent=(x[0] - sx / 2, x[-1] + sx / 2, y[0] - sy / 2,
                                       y[-1] + sy / 2))
        plane = "max over z" if self.grid.shape[2] > 1 else f"z = {self.grid.origin[2]:g} m"
        self.fig.colorbar(image, ax=self.ax, shrink=0.8, label=f"(joint likelihood / frame's "
                          f"peak) ^ (1/{self.n_detectors}), {plane}")
        self.ax.set(xlabel="x (m)", ylabel="y (m), distance from the wall")
        self.ax.set_title("frame 0, t = 0.00 s", fontsize=10)  # (laid out with a title)
        edge = [patheffects.withStroke(linewidth=2.5, foreground="black")]  # seen on the peak
        self.style = {"truth": dict(ls="", marker="+", color="lime", ms=10, mew=1.5),
                      "measurement": dict(ls="", marker="x", color="white", ms=6, mew=1.5),
                      "track, 2-sigma ellipse": dict(color="cyan", lw=1.2)}
        for style in self.style.values():
            style["path_effects"] = edge
        self.ax.legend(handles=[Line2D([], [], label=k, **v) for k, v in self.style.items()],
                       loc="upper right", fontsize=7, framealpha=0.6)
        return image

    def draw(self, frame, tracks, measurements, scores) -> None:
        """Redraw the figure for one frame; scores: joint_map's (ny, nx) map or None."""
        import numpy as np
        shown = _display(scores, self.log_mode, self.n_detectors)
        self.image.set_data(np.zeros(self.grid.shape[1::-1]) if shown is None else shown)
        for artist in self.overlay:
            artist.remove()
        ax, drawn, (truth, meas, track) = self.ax, [], self.style.values()
        ax.set_title(f"frame {frame.index}, t = {frame.t_s:.2f} s"
                     + (" (no map)" if shown is None else ""), fontsize=10)
        if frame.truths is not None:
            drawn += ax.plot(frame.truths[:, 0], frame.truths[:, 1], **truth)
        for m in measurements:
            drawn += ax.plot(*m.position[:2], **meas)
        ang = np.linspace(0, 2 * np.pi, 60)
        for t in tracks:  # trail: the last 30 positions; dotted ellipse: a tentative track
            trail = np.array([(h[2], h[3]) for h in list(t.history)[-30:]]).reshape(-1, 2)
            w, v = np.linalg.eigh(t.covariance[:2, :2])
            ell = v @ (2 * np.sqrt(np.maximum(w, 0))[:, None] * [np.cos(ang), np.sin(ang)])
            p = t.position
            drawn += ax.plot(trail[:, 0], trail[:, 1], color="cyan", lw=0.8, alpha=0.8)
            drawn += ax.plot(p[0] + ell[0], p[1] + ell[1], **track,
                             ls="-" if t.status == "confirmed" else ":")
            drawn.append(ax.annotate(str(t.id), p[:2], color="cyan", fontsize=9,
                                     xytext=(5, 5), textcoords="offset points",
                                     path_effects=track["path_effects"]))
        self.overlay = drawn


class _GifWriter:
    """A GIF written frame by frame, with matplotlib's writer interface (saving, grab_frame):
    matplotlib's PillowWriter keeps every frame in memory until the last (0.9 MB each at 600 x
    500 pixels). Each frame gets its own 256-colour palette (fast octree), through
    Pillow's GIF frame encoder (GifImagePlugin.getheader / getdata)."""

    def __init__(self, fps: int):
        self.fps, self.fig, self.dpi, self._fh, self._frames = fps, None, None, None, 0

    def saving(self, fig, outfile, dpi):
        import contextlib

        @contextlib.contextmanager
        def context():
            self.fig, self.dpi, self._frames = fig, dpi, 0
            self._fh = open(outfile, "wb")
            try:
                yield self
            finally:
                self.finish()
        return context()

    def grab_frame(self) -> None:
        from io import BytesIO

        from PIL import GifImagePlugin, Image
        buf = BytesIO()
        self.fig.savefig(buf, format="rgba", dpi=self.dpi)
        w, h = self.fig.get_size_inches()
        size = int(w * self.dpi + 1e-8), int(h * self.dpi + 1e-8)
        im = Image.frombuffer("RGBA", size, buf.getbuffer(), "raw", "RGBA", 0, 1)
        im = im.convert("RGB").quantize(256, method=Image.Quantize.FASTOCTREE)  # ~5x median cut
        ms = int(round(1000 / self.fps))
        if self._frames == 0:  # the first frame's palette as the global one, loop forever
            self._fh.write(b"".join(GifImagePlugin.getheader(im, None, {"loop": 0,
                                                                        "duration": ms})[0]))
        self._fh.write(b"".join(GifImagePlugin.getdata(im, (0, 0), duration=ms,
                                                       include_color_table=True)))
        self._frames += 1

    def finish(self) -> None:
        if self._fh is not None:
            fh, self._fh = self._fh, None
            with fh:
                fh.write(b";")  # the GIF trailer
