"""`nlos-cl track --video`: the animation written while tracking (nlos_cl/apps/track.py drives
it): each frame's joint map (the Locator's scores over the whole grid, shown as `_display`
says) under the tracks (2-sigma error ellipses, trails), the measurements and the truths, seen
from above along the file's own axes (`TopView`: X across and Z from the wall for a y-tal file),
one frame in memory at a time; the file appears only when complete.
It scores the whole grid once more each frame (the tracker's own search need not score every
cell), so --video costs that much extra per frame.
"""
from __future__ import annotations


def check_video_path(args) -> None:
    from pathlib import Path

    from ..core.errors import require
    from ..io.safe_write import require_writable
    path = Path(args.video)
    require(path.suffix in (".gif", ".mp4"), "--video", f"{path} is neither .gif nor .mp4",
            "pass e.g. tracks.gif")
    require(path.parent.is_dir(), "--video", f"the folder {path.parent} does not exist",
            "pass a path in an existing folder")
    # the rule every writer follows (links, non-regular files, files nlos_cl did not write),
    # checked before tracking: atomic_write applies it again when the video is complete
    require_writable(path, force=args.force, what="--video", kind="a video")
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


MAX_PIXELS = 1200  # a 6 x 5 inch figure at 100 dpi shows ~500 map pixels a side


def pooled_shape(shape) -> tuple:
    """(rows, columns) of a map of `shape` after `pooled`."""
    return tuple(-(-n // -(-n // MAX_PIXELS)) for n in shape)


def pooled(scores):
    """The (ny, nx) map reduced by block maxima to at most MAX_PIXELS a side (peaks kept):
    the figure cannot show more, and matplotlib's resampling of a huge image copies it several
    times (3 GB for a 2000 x 1000 x 1000 grid)."""
    import numpy as np
    fy, fx = (-(-n // MAX_PIXELS) for n in scores.shape)
    if fy == fx == 1:
        return scores
    ny, nx = (-(-n // f) * f for n, f in zip(scores.shape, (fy, fx)))
    padded = np.full((ny, nx), -np.inf)
    padded[:scores.shape[0], :scores.shape[1]] = scores
    return padded.reshape(ny // fy, fy, nx // fx, fx).max(axis=(1, 3))


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


class TopView:
    """The video's plane in the file's frame: the file axes along ours x (across the wall) and y
    (from it), each with its sign, where the frame permutes axes (a y-tal file: X = -x, Z = y);
    a fitted wall's rotated frame is shown along the wall's own axes, so named."""

    def __init__(self, frame):
        import numpy as np
        m = np.asarray(frame.matrix)
        self.frame = frame
        if frame.is_permutation:
            self.lat, self.dep = (int(np.argmax(np.abs(m[j]))) for j in (0, 1))
            self.signs = (float(m[0, self.lat]), float(m[1, self.dep]))
            self.labels = (f"{frame.axes[self.lat]} (m), along the wall",
                           f"{frame.axes[self.dep]} (m), distance from the wall")
            self.up = frame.axes[int(np.argmax(np.abs(m[2])))]
        else:
            self.lat, self.dep, self.signs = None, None, (1.0, 1.0)
            self.labels = ("along the wall (m), fitted wall's frame",
                           "distance from the wall (m)")
            self.up = "height"

    def points(self, internal):
        """(N, 2) view coordinates of points of ours (N, 3)."""
        import numpy as np
        p = np.atleast_2d(np.asarray(internal, dtype=np.float64))
        if self.lat is None:
            return p[:, :2]
        return np.atleast_2d(self.frame.from_internal(p))[:, [self.lat, self.dep]]

    def image(self, shown):
        """A (ny, nx) map along ours as the view shows it (flipped where a sign is negative)."""
        sx, sy = self.signs
        return shown[::-1 if sy < 0 else 1, ::-1 if sx < 0 else 1]

    def extent(self, grid):
        """The image's (left, right, bottom, top) in view coordinates, increasing."""
        (x, y, _), (dx, dy, _) = grid.axes(), grid.step
        corners = [[x[0] - dx / 2, y[0] - dy / 2, 0.0], [x[-1] + dx / 2, y[-1] + dy / 2, 0.0]]
        corners[0][2] = corners[1][2] = float(grid.origin[2])
        (u0, v0), (u1, v1) = self.points(corners)
        return (min(u0, u1), max(u0, u1), min(v0, v1), max(v0, v1))


class Video:
    """`with Video(path, tmp, tracker) as v: v.add(frame, tracks, measurements)` after each
    tracker.update: each frame drawn and written as it comes (nothing kept per frame), into `tmp`
    (atomic_write's temporary). An .mp4 goes through ffmpeg, which picks the format by suffix:
    written beside as tmp.mp4, moved onto tmp on leaving the `with`; an exception removes it."""

    FPS, DPI = 10, 100

    def __init__(self, path: str, tmp: str, tracker, frame=None):
        from ..core.limits import require_memory
        from ..io.ytal.frames import INTERNAL
        from .plotting import pyplot
        self.tracker, self.grid, self.log_mode = tracker, tracker.grid, tracker.locator.log_mode
        self.view = TopView(INTERNAL if frame is None else frame)
        # a frame's map: the device's scores, read back (float32, then float64), its z-maximum
        # and the picture (pooled, but first a few float64 planes of the whole grid)
        nx, ny, _ = self.grid.shape
        require_memory("--region", 16.0 * self.grid.n_cells + 24.0 * nx * ny, f"the video's map "
                       f"of {self.grid.n_cells:.3g} cells", "a smaller --region or a larger --step")
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

    def add(self, frame, tracks, measurements) -> None:
        """Draw this frame (the tracker's last: its joint map) and write it to the video."""
        self.draw(frame, tracks, measurements, joint_map(self.tracker))
        self.writer.grab_frame()

    def _axes(self):
        """The map's image (updated per frame), colour bar, labels and legend."""
        import numpy as np
        from matplotlib import patheffects
        from matplotlib.lines import Line2D
        view = self.view
        image = self.ax.imshow(np.zeros(pooled_shape(self.grid.shape[1::-1])), origin="lower",
                               cmap="magma",
                               vmin=0.0, vmax=1.0, aspect="equal",  # (fine grids: smoothed)
                               extent=view.extent(self.grid))
        plane = f"max over {view.up}" if self.grid.shape[2] > 1 else "one height"
        self.fig.colorbar(image, ax=self.ax, shrink=0.8, label=f"(joint likelihood / frame's "
                          f"peak) ^ (1/{self.n_detectors}), {plane}")
        self.ax.set(xlabel=view.labels[0], ylabel=view.labels[1])
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
        shown = _display(None if scores is None else pooled(scores), self.log_mode,
                         self.n_detectors)
        self.image.set_data(np.zeros(pooled_shape(self.grid.shape[1::-1])) if shown is None
                            else self.view.image(shown))
        for artist in self.overlay:
            artist.remove()
        ax, drawn, (truth, meas, track) = self.ax, [], self.style.values()
        ax.set_title(f"frame {frame.index}, t = {frame.t_s:.2f} s"
                     + (" (no map)" if shown is None else ""), fontsize=10)
        view = self.view
        if frame.truths is not None:
            drawn += ax.plot(*view.points(frame.truths).T, **truth)
        for m in measurements:
            drawn += ax.plot(*view.points(m.position).T, **meas)
        ang = np.linspace(0, 2 * np.pi, 60)
        for t in tracks:  # trail: the last 30 positions; dotted ellipse: a tentative track
            trail = np.array([h[2:5] for h in list(t.history)[-30:]]).reshape(-1, 3)
            w, v = np.linalg.eigh(t.covariance[:2, :2])
            ell = v @ (2 * np.sqrt(np.maximum(w, 0))[:, None] * [np.cos(ang), np.sin(ang)])
            ring = np.column_stack([t.position[0] + ell[0], t.position[1] + ell[1],
                                    np.full(ang.size, t.position[2])])
            p = view.points(t.position)[0]
            drawn += ax.plot(*view.points(trail).T, color="cyan", lw=0.8, alpha=0.8)
            drawn += ax.plot(*view.points(ring).T, **track,
                             ls="-" if t.status == "confirmed" else ":")
            drawn.append(ax.annotate(str(t.id), p, color="cyan", fontsize=9,
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
