"""Lazy reading of sequence files (the layout is documented in nlos_cl/tracking/sequence.py).

`read_sequence(path)` checks the file (truncation, the y-tal fields, frame 0 with capture.py's
own reader) and returns a `Sequence`; iterating it opens the file once and reads one frame per
step (`H[k]`, an h5py slice), so memory stays flat however long the recording is.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.errors import InputError, require, shown
from .checks import unreadable
from .sequence import SequenceFrame, check_frame_times


class _FrameView:
    """Frame k of a sequence's H, shaped like a capture's H for fields.to_histograms."""

    def __init__(self, dataset, k):
        self._d, self._k = dataset, k
        self.shape, self.dtype = tuple(dataset.shape[1:]), dataset.dtype

    def __getitem__(self, index):
        index = index if isinstance(index, tuple) else (index,)
        return self._d[(self._k,) + index]


def _sequence_info(scene_info, path) -> dict:
    from .fields import our_metadata
    ours = our_metadata(scene_info, path) or {}
    meta = ours.get("metadata") if isinstance(ours, dict) else None
    info = meta.get("sequence") if isinstance(meta, dict) else None
    return {"metadata": meta if isinstance(meta, dict) else {},
            "sequence": info if isinstance(info, dict) else {}}


# what h5py raises on damaged bytes, besides InputError from the checks
READ_ERRORS = (OSError, RuntimeError, LookupError, ValueError, TypeError, AttributeError,
               OverflowError)


def _declared_frames(f, where) -> int:
    """H's frame count, as declared: a leading frame axis, at most MAX_FRAMES frames."""
    import h5py

    from ...core.limits import MAX_FRAMES, require_count
    H = f["H"]
    require(isinstance(H, h5py.Dataset) and H.ndim is not None and H.ndim >= 3, f"{where}: H",
            f"has shape {getattr(H, 'shape', None)}, expected a leading frame axis (F, T, S)",
            "write it with nlos_cl.tracking.write_sequence")
    return require_count(f"{where}: H", int(H.shape[0]), MAX_FRAMES, "frames declared",
                         "split the recording into sequences of fewer frames")


def _frame_times(f, where, n_frames) -> np.ndarray:
    """frame_t_s: (F,) finite seconds, strictly increasing, spaced like a frame rate."""
    import h5py
    d = f["frame_t_s"]
    ok = isinstance(d, h5py.Dataset) and d.shape is not None and np.issubdtype(d.dtype, np.number)
    require(ok, f"{where}: frame_t_s", f"is {getattr(d, 'dtype', 'a group')}, not numbers",
            "store the frames' times as float64 seconds (write_sequence does)")
    size = int(np.prod(d.shape, dtype=np.float64))  # checked before it is read
    require(size == n_frames and n_frames >= 1, f"{where}: frame_t_s", f"has {size:,} "
            f"entries for {n_frames:,} frames", "store one time per frame of H")
    t = np.asarray(d[()], dtype=np.float64).reshape(-1)
    check_frame_times(t, f"{where}: frame_t_s")
    return t


def _frame_truths(f, where, n_frames) -> None:
    """frame_truths, when present: (F, K, 3) numbers (NaN where unknown)."""
    import h5py
    if "frame_truths" not in f:
        return
    d = f["frame_truths"]
    shape = getattr(d, "shape", None)
    ok = isinstance(d, h5py.Dataset) and shape is not None and np.issubdtype(d.dtype, np.number)
    require(ok and len(shape) == 3 and shape[0] == n_frames and shape[2] == 3,
            f"{where}: frame_truths", f"is {getattr(d, 'dtype', 'a group')} "
            f"{shape if ok else ''}, expected numbers of shape ({n_frames}, K, 3): K targets' "
            "(x, y, z) per frame", "store it as write_sequence does (NaN where unknown)")
    return int(shape[1])


def _single_frame(seq: dict, where) -> tuple:
    """A one-frame sequence's time and truths, from scene_info's nlos_cl.metadata.sequence."""
    t_s, truths = seq.get("t_s") or [0.0], (seq.get("truths") or [None])[0]
    ok = isinstance(t_s, list) and len(t_s) >= 1 and isinstance(t_s[0], (int, float)) and \
        not isinstance(t_s[0], bool) and np.isfinite(t_s[0])
    require(ok, f"{where}: scene_info sequence.t_s", f"expected [time in seconds], got {shown(t_s)}",
            "write the frame again with nl.tracking.write_sequence")
    if truths is None:
        return np.array(t_s[:1], dtype=np.float64), None
    try:
        truths = np.asarray(truths, dtype=np.float64)
    except (TypeError, ValueError):
        truths = np.zeros(0)
    require(truths.ndim == 2 and truths.shape[1] == 3, f"{where}: scene_info sequence.truths",
            "expected [[x, y, z], ...] per target", "write the frame again with "
            "nl.tracking.write_sequence")
    return np.array(t_s[:1], dtype=np.float64), truths


class Sequence:
    """A sequence file opened for lazy reading. `layout` (frame 0's, without truth), `frame`
    (the file's coordinate frame, nlos_cl.io.ytal.frames.YTAL), `t_s` (F,) timestamps, `metadata`
    (what the writer passed), `fps` (if recorded); `len(seq)`, `seq[k]`, `for f in seq`."""

    def __init__(self, path, *, max_frame_bytes: int | None = None):
        import h5py

        from .capture import read_capture_with_frame
        from .fields import (
            check_complete,
            check_memory,
            check_regular,
            check_storage,
            dataset,
        )
        self.path = Path(path)
        where = f"sequence {self.path}"
        check_regular(self.path, "sequence")
        check_complete(self.path)
        try:
            with h5py.File(self.path, "r") as f:
                check_storage(f, self.path, "sequence")  # links, external storage: refused first
                require("H" in f, where, "has no field H",
                        "write it with nlos_cl.tracking.write_sequence")
                stacked = "frame_t_s" in f
                if stacked:  # what a frame holds (count, sizes, chunks) before any field is read
                    self.n_frames = _declared_frames(f, where)
                check_memory(f, self.path, max_frame_bytes if stacked else None, "sequence",
                             frames=stacked)
                info = _sequence_info(dataset(f, "scene_info", self.path) if "scene_info" in f
                                      else None, self.path)
        except InputError:
            raise
        except READ_ERRORS as exc:  # a lock, a file HDF5 cannot open, damaged bytes
            raise unreadable(exc, self.path, what="sequence") from None
        self.metadata = {k: v for k, v in info["metadata"].items() if k != "sequence"}
        self.fps = info["sequence"].get("fps")
        if not stacked:  # a plain capture: one frame
            sets, self.frame = read_capture_with_frame(self.path)
            require(len(sets) == 1, where, f"has {len(sets)} laser points", "track captures "
                    "with one laser point (split the others into their own files)")
            self._single = sets[0]
            self.t_s, self._single_truths = _single_frame(info["sequence"], where)
            if self._single_truths is None and sets[0].truth is not None:
                self._single_truths = np.asarray(sets[0].truth, float).reshape(1, 3)
            self.layout = sets[0].layout
            self.n_frames = 1
            return
        self._single = None
        self._open_stacked(where)

    def _open_stacked(self, where):
        import h5py

        from .fields import FIELDS, REQUIRED, dataset, to_histograms
        try:
            with h5py.File(self.path, "r") as f:
                missing = [k for k in REQUIRED if k not in f]
                require(not missing, where, f"missing field(s) {missing}",
                        "write every field of y-tal's NLOSCaptureData (see nlos_cl.io.ytal.capture)")
                H = f["H"]
                fields = {k: dataset(f, k, self.path) for k in FIELDS if k in f}
                self.t_s = _frame_times(f, where, self.n_frames)
                _frame_truths(f, where, self.n_frames)
                sets, frame = to_histograms(fields, _FrameView(H, 0), self.path, with_frame=True)
                require(len(sets) == 1, where, f"has {len(sets)} laser points per frame",
                        "write one laser point (or one per histogram: paired) per sequence")
                require(int(np.prod(H.shape[2:])) == sets[0].n_detectors, f"{where}: H",
                        f"has shape {H.shape}: a trailing Stokes axis (polarized frames)",
                        "write each frame's first Stokes channel (S0) only")
        except InputError:
            raise
        except READ_ERRORS as exc:
            raise unreadable(exc, self.path, what="sequence") from None
        self._first, self.frame = sets[0], frame
        self.layout = sets[0].layout

    def __len__(self) -> int:
        return self.n_frames

    def _make(self, k, data, truths) -> SequenceFrame:
        from ...core.histograms import HistogramSet
        h = self._first
        bad = int(data.size - np.count_nonzero(np.isfinite(data)))
        require(bad == 0, f"sequence {self.path}: H[{k}]", f"{bad} values are NaN or inf",
                "replace missing bins by 0 before writing")
        if truths is not None and truths.size:  # stored in YTAL's internal axes (wall.ours_in)
            from .wall import ours_in
            truths = ours_in(self.frame, truths.reshape(-1, 3)).reshape(truths.shape)
        truth = None
        if truths is not None and np.all(np.isfinite(truths[0])):
            truth = truths[0]
        hist = HistogramSet(data, h.time_axis, h.detector_spots, h.laser_spot, h.calibration,
                            truth=truth, allow_negative=h.allow_negative,
                            truths=None if truths is None else truths)
        return SequenceFrame(k, float(self.t_s[k]), hist, truths)

    def frames(self, start: int = 0, stop: int | None = None):
        """Frames start..stop-1, read one at a time (the file stays open while iterating)."""
        import h5py
        stop = self.n_frames if stop is None else min(int(stop), self.n_frames)
        if self._single is not None:
            if start <= 0 < stop:
                h, truths = self._single, self._single_truths
                if truths is not None:
                    from dataclasses import replace
                    h = replace(h, truth=truths[0], truths=truths)
                yield SequenceFrame(0, float(self.t_s[0]), h, truths)
            return
        with h5py.File(self.path, "r") as f:
            H = f["H"]
            R = f.get("frame_truths")
            n_t = H.shape[1]
            for k in range(max(int(start), 0), stop):
                try:
                    data = np.asarray(H[k], dtype=np.float64).reshape(n_t, -1).T
                    truths = None if R is None else np.asarray(R[k], float)
                except (OSError, RuntimeError) as exc:  # a missing filter, a cut-off chunk
                    raise unreadable(exc, self.path, f"H[{k}]", "sequence", H) from None
                yield self._make(k, data, truths)

    def __iter__(self):
        return self.frames()

    def __getitem__(self, k: int) -> SequenceFrame:
        require(isinstance(k, (int, np.integer)) and -self.n_frames <= k < self.n_frames,
                "frame", f"index {shown(k)} outside 0..{self.n_frames - 1}", "pass a valid index")
        k = int(k) % self.n_frames
        return next(self.frames(k, k + 1))


def read_sequence(path, *, max_frame_bytes: int | None = None) -> Sequence:
    """Open a sequence file (or a plain y-tal capture, read as one frame) for lazy reading."""
    return Sequence(path, max_frame_bytes=max_frame_bytes)
