"""Sequences of frames in one HDF5 file: y-tal's capture fields with a leading frame axis.

A sequence of F >= 2 frames is a y-tal capture (nlos_cl/capture.py's field table, written by
the same code) in which `H` gets a leading frame axis, plus two per-frame datasets:

| field | dtype, shape | meaning |
|---|---|---|
| H | float32 (F, T, S), H_format T_Si; (F, T, Sx, Sy), T_Sx_Sy, for a confocal grid (grid_write.scan_grid); chunked one frame per chunk | frame k's histograms, time first as in y-tal |
| frame_t_s | float64 (F,) | frame k's timestamp (s), e.g. k / fps |
| frame_truths | float64 (F, K, 3), optional | the K targets' true centres per frame, nlos_cl's internal frame (as the capture's `truth`), NaN where unknown |
| every other y-tal field | as in a capture | the same for all frames: the laser point (or one per histogram: paired, confocal), the sensor grid, delta_t, t_start, ... |
| scene_info | YAML | as a capture's; `nlos_cl.metadata.sequence` holds {format_version, n_frames, fps, fields} |

A single frame is written as a plain y-tal capture (H (T, S), no extra fields; its timestamp
and truths ride in `scene_info`'s `nlos_cl.metadata.sequence`), and every plain capture reads
back as a one-frame sequence. Paired frames (a laser spot per histogram) are written and read
like a paired capture; exhaustive frames (several laser points, each with every sensor point)
are not supported in sequences.

Writing streams frames from any iterator into the file (only one frame in memory) and is atomic
(nlos_cl.io.safe_write.atomic_write: an interrupted write leaves the old file). Reading is lazy:
`read_sequence(path)` checks the fields and frame 0, and iterating reads one frame at a time
with h5py slicing, so a recording longer than memory is tracked with flat memory.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ...core.errors import require, shown
from ...core.stats import median
from .grid_write import GridFile, in_grid_order, mark_grid, scan_grid

FORMAT_VERSION = 1
GROW = 256  # frames added to H's size at a time while writing


@dataclass(frozen=True)
class SequenceFrame:
    """One frame read back: index, timestamp (s), histograms (W or counts; truth attached) and
    the targets' true centres (K, 3) in our frame, or None."""

    index: int
    t_s: float
    histograms: object  # nl.HistogramSet
    truths: np.ndarray | None


# ---------------------------------------------------------------------------- writing

def _as_entry(item, k, fps):
    """(t_s, HistogramSet, truths) from a SimFrame, SequenceFrame, HistogramSet, Signals, or a
    (t_s, histograms[, truths]) tuple."""
    from ...core.histograms import HistogramSet
    from ...ops.signals import Signals
    truths = None
    if isinstance(item, tuple):
        require(len(item) in (2, 3), f"frames[{k}]", "a tuple must be (t_s, histograms) or "
                "(t_s, histograms, truths)", "pass SimFrames or such tuples")
        t, hist = float(item[0]), item[1]
        truths = item[2] if len(item) == 3 else None
    elif hasattr(item, "t_s") and (hasattr(item, "signals") or hasattr(item, "histograms")):
        t, hist, truths = item.t_s, getattr(item, "signals", None), item.truths
        hist = item.histograms if hist is None else hist
    else:
        require(fps is not None, "fps", "is needed to time frames given without timestamps",
                "pass fps=..., or (t_s, histograms) pairs")
        t, hist = k / fps, item
    if isinstance(hist, Signals):
        hist = hist.histograms()
    require(isinstance(hist, HistogramSet), f"frames[{k}]", f"expected histograms, got "
            f"{type(hist).__name__}", "pass nl.HistogramSet or nl.Signals frames")
    require(math.isfinite(float(t)), f"frames[{k}].t_s", f"is {t}", "pass finite timestamps")
    if truths is None:
        truths = hist.truths if hist.truths is not None else hist.truth
    truths = None if truths is None else np.asarray(truths, np.float64).reshape(-1, 3)
    return float(t), hist, truths


def _same_layout(a, b, k):
    same = (a.data.shape == b.data.shape and a.time_axis == b.time_axis
            and np.array_equal(a.detector_spots, b.detector_spots)
            and np.array_equal(a.laser_spot, b.laser_spot)
            and np.array_equal(a.calibration.offsets(a.n_detectors),
                               b.calibration.offsets(b.n_detectors))
            and a.calibration.a_m_per_s == b.calibration.a_m_per_s)
    require(same, f"frames[{k}]", "has another shape, time axis, wall layout or calibration "
            "than frame 0", "write frames of one setup into one sequence")


def write_sequence(path, frames, *, fps: float | None = None, device_distance_m: float = 20.0,
                   metadata: dict | None = None, compression: int = 0, force: bool = False
                   ) -> Path:
    """Write `frames` (an iterable, consumed one frame at a time) as a sequence file. Items:
    SimFrames (from simulate_sequence), SequenceFrames, (t_s, histograms[, truths]) tuples, or
    HistogramSet/Signals timed k / fps. compression: gzip level (0: none, the fastest)."""
    from ..safe_write import atomic_write
    from .fields import is_capture
    require(compression in range(10), "compression", f"must be a gzip level 0-9, got "
            f"{shown(compression)}", "pass 0 (none) or 4")
    require(fps is None or (isinstance(fps, (int, float)) and math.isfinite(fps) and fps > 0),
            "fps", f"must be a positive frame rate, got {shown(fps)}", "pass e.g. 10")

    def write(tmp):
        _write(tmp, iter(frames), fps, device_distance_m, metadata, compression)
    return atomic_write(path, write, keep_unless=is_capture, force=force, record=False,
                        what="sequence",
                        kind="an HDF5 capture or sequence")


def _info(fps, n, truths, t=None):
    info = {"format_version": FORMAT_VERSION, "n_frames": n, "fps": fps,  # n: None = H's F
            "fields": {"H": "leading frame axis", "frame_t_s": "s", "frame_truths":
                       "(F, K, 3) m, nlos_cl internal frame"}}
    if t is not None:  # a single frame: a plain capture, its time and truths here
        info = {**info, "fields": None, "t_s": [float(t)],
                "truths": None if truths is None else [truths.tolist()]}
    return info


def _write(tmp, it, fps, device_distance_m, metadata, compression):
    import h5py
    first = next(it, None)
    require(first is not None, "frames", "is empty", "pass at least one frame")
    t0, h0, truths0 = _as_entry(first, 0, fps)
    _check_capture(h0, device_distance_m)
    grid = scan_grid(h0)  # a confocal grid: y-tal's grid layout, as write_capture writes it
    h0 = h0 if grid is None else in_grid_order(h0, grid)
    second = next(it, None)
    meta = dict(metadata or {})
    bare = replace(h0, truth=None, truths=None)
    if second is None:
        meta["sequence"] = _info(fps, 1, truths0, t0)
        with h5py.File(tmp, "w") as f:
            _fields(f, bare, device_distance_m, meta, compression, True, grid)
        return 1
    meta["sequence"] = _info(fps, None, truths0)
    with h5py.File(tmp, "w") as f:
        _fields(f, bare, device_distance_m, meta, compression, False, grid)
        n = _stream(f, (first, second), it, fps, h0, truths0, compression, grid)
    return n


def _check_capture(h, device_distance_m):
    from .fields import check_writable
    check_writable(h, device_distance_m)


def _fields(f, hist, device_distance_m, meta, compression, keep_h, grid):
    """capture.py's own writer, into memory; its fields copied (H only for a single frame);
    with a grid (rows already in its order) in y-tal's grid layout, as grid_write writes it."""
    import h5py

    from .fields import write_fields
    with h5py.File(f"nlos_seq_{id(f)}", "w", driver="core", backing_store=False) as mem:
        write_fields(mem if grid is None else GridFile(mem, grid.shape), hist,
                     device_distance_m, meta, compression)
        if grid is not None:
            mark_grid(mem)
        for key in mem:
            if keep_h or key != "H":
                mem.copy(mem[key], f, name=key)


def _stream(f, head, it, fps, h0, truths0, compression, grid):
    from itertools import chain
    n_s, n_t = h0.data.shape
    frame = (n_t, n_s) if grid is None else (n_t,) + tuple(grid.shape)
    k_targets = 0 if truths0 is None else len(truths0)
    H = f.create_dataset("H", (0,) + frame, maxshape=(None,) + frame, dtype=np.float32,
                         chunks=(1,) + frame, compression="gzip" if compression else None,
                         compression_opts=compression or None)
    T = f.create_dataset("frame_t_s", (0,), maxshape=(None,), dtype=np.float64, chunks=(4096,))
    R = None if not k_targets else f.create_dataset(
        "frame_truths", (0, k_targets, 3), maxshape=(None, k_targets, 3), dtype=np.float64,
        chunks=(1024, k_targets, 3))
    n, room = 0, _Room(f.filename, 4 * n_s * n_t)
    for k, item in enumerate(chain(head, it)):
        t, h, truths = _as_entry(item, k, fps)
        if grid is not None and h.n_detectors == h0.n_detectors:  # else _same_layout refuses
            h = in_grid_order(h, grid)
        _same_layout(h0, h, k)
        room.check(n)
        if n == H.shape[0]:
            for d in (H, T) + ((R,) if R is not None else ()):
                d.resize(n + GROW, axis=0)
        H[n] = np.ascontiguousarray(h.data.T, dtype=np.float32).reshape(frame)
        T[n] = t
        if R is not None:
            row = np.full((k_targets, 3), np.nan)
            if truths is not None:
                row[:min(len(truths), k_targets)] = truths[:k_targets]
            R[n] = row
        n += 1
    for d in (H, T) + ((R,) if R is not None else ()):
        d.resize(n, axis=0)
    check_frame_times(T[()], "frames.t_s")
    return n


class _Room:
    """Free space for the next frames, checked before HDF5 writes them: HDF5 meeting a full
    disk leaves a file it cannot close and ended in a segfault. A frame is written only while
    the disk holds LOOKAHEAD more (uncompressed) frames and HEADROOM_BYTES for HDF5's
    metadata; the free space is asked every LOOKAHEAD frames (one statvfs)."""

    def __init__(self, path, frame_bytes: int):
        self.folder, self.frame_bytes, self.free = Path(path).parent, frame_bytes, 0

    def check(self, n: int) -> None:
        need = (LOOKAHEAD + 1) * self.frame_bytes + HEADROOM_BYTES
        if n % LOOKAHEAD == 0 or self.free < need:
            import shutil
            self.free = shutil.disk_usage(self.folder).free
        require(self.free >= need, f"sequence {self.folder}", f"the disk has "
                f"{self.free / 2**20:.1f} MiB free, and the next frames need "
                f"{need / 2**20:.1f} MiB (after {n} frames written; nothing is kept)",
                "free space there, or write the sequence to another disk")
        self.free -= self.frame_bytes


HEADROOM_BYTES, LOOKAHEAD = 1 << 20, 8

# A sequence is for tracking motion: frames more than this apart (median) are not a frame
# rate (a walker moves 14 m in 10 s, beyond any hidden scene the ellipse model covers), but
# timestamps in ms (10 fps: 100 apart) or us. Writer and reader refuse the same files.
MAX_FRAME_SPACING_S = 10.0


def check_frame_times(t, field: str) -> None:
    """Timestamps (s): finite, strictly increasing, spaced like a frame rate."""
    t = np.asarray(t, dtype=np.float64)
    require(bool(np.all(np.isfinite(t))), field, "contains NaN or inf", "store finite times (s)")
    require(bool(np.all(np.diff(t) > 0)), field, "timestamps must increase strictly from frame "
            "to frame", "pass frames in time order")
    gap = median(np.diff(t)) if t.size > 1 else 0.0
    unit, short, factor = (("milliseconds", "ms", 1e3) if gap < 1e4 else
                           ("microseconds", "us", 1e6) if gap < 1e7 else ("nanoseconds", "ns", 1e9))
    require(gap <= MAX_FRAME_SPACING_S, field, f"frames are {gap:.4g} s apart (median), "
            f"{1 / gap:.3g} frames per second: that looks like {unit} ({gap:.4g} {short} is "
            f"{factor / gap:.3g} fps)", f"store seconds (divide by {factor:g})")
