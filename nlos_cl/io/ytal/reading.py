"""Lazy reading of sequence files (the layout is documented in nlos_cl/tracking/sequence.py).

`read_sequence(path)` checks the file (truncation, the y-tal fields, frame 0 with capture.py's
own reader) and returns a `Sequence`; iterating it opens the file once and reads one frame per
step (`H[k]`, an h5py slice), so memory stays flat however long the recording is.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.errors import InputError, require
from .sequence import SequenceFrame


class _FrameView:
    """Frame k of a sequence's H, shaped like a capture's H for fields.to_histograms."""

    def __init__(self, dataset, k):
        self._d, self._k = dataset, k
        self.shape, self.dtype = tuple(dataset.shape[1:]), dataset.dtype

    def __getitem__(self, index):
        index = index if isinstance(index, tuple) else (index,)
        return self._d[(self._k,) + index]


def _sequence_info(scene_info) -> dict:
    from .fields import our_metadata
    ours = our_metadata(scene_info) or {}
    meta = ours.get("metadata") if isinstance(ours, dict) else None
    info = meta.get("sequence") if isinstance(meta, dict) else None
    return {"metadata": meta if isinstance(meta, dict) else {},
            "sequence": info if isinstance(info, dict) else {}}


class Sequence:
    """A sequence file opened for lazy reading. `layout` (frame 0's, without truth), `frame`
    (the file's coordinate frame, nlos_cl.io.ytal.frames.YTAL), `t_s` (F,) timestamps, `metadata`
    (what the writer passed), `fps` (if recorded); `len(seq)`, `seq[k]`, `for f in seq`."""

    def __init__(self, path, *, max_frame_bytes: int | None = None):
        import h5py

        from .capture import read_capture_with_frame
        from .fields import check_complete, check_storage
        self.path = Path(path)
        where = f"sequence {self.path}"
        require(self.path.is_file(), where, "does not exist", "pass the path of an .h5 file")
        check_complete(self.path)
        with h5py.File(self.path, "r") as f:
            check_storage(f, self.path)  # links and external storage: refused before any field
            require("H" in f, where, "has no field H",
                    "write it with nlos_cl.tracking.write_sequence")
            stacked = "frame_t_s" in f
            info = _sequence_info(f["scene_info"][()] if "scene_info" in f else None)
        self.metadata = {k: v for k, v in info["metadata"].items() if k != "sequence"}
        self.fps = info["sequence"].get("fps")
        if not stacked:  # a plain capture: one frame
            sets, self.frame = read_capture_with_frame(self.path)
            require(len(sets) == 1, where, f"has {len(sets)} laser points", "track captures "
                    "with one laser point (split the others into their own files)")
            self._single = sets[0]
            seq = info["sequence"]
            self.t_s = np.array(seq.get("t_s") or [0.0], dtype=np.float64)[:1]
            truths = (seq.get("truths") or [None])[0]
            self._single_truths = None if truths is None else np.asarray(truths, float)
            if self._single_truths is None and sets[0].truth is not None:
                self._single_truths = np.asarray(sets[0].truth, float).reshape(1, 3)
            self.layout = sets[0].layout
            self.n_frames = 1
            return
        self._single = None
        self._open_stacked(where, max_frame_bytes)

    def _open_stacked(self, where, max_frame_bytes):
        import h5py

        from ...core.limits import memory_limit
        from .fields import REQUIRED, dataset, to_histograms
        from .frames import YTAL
        try:
            with h5py.File(self.path, "r") as f:
                missing = [k for k in REQUIRED if k not in f]
                require(not missing, where, f"missing field(s) {missing}",
                        "write every field of y-tal's NLOSCaptureData (see nlos_cl.io.ytal.capture)")
                H = f["H"]
                require(isinstance(H, h5py.Dataset) and H.ndim >= 3, f"{where}: H",
                        f"has shape {getattr(H, 'shape', None)}, expected a leading frame "
                        "axis (F, T, S)", "write it with nlos_cl.tracking.write_sequence")
                per_frame = 12.0 * int(np.prod(H.shape[1:], dtype=np.float64))
                limit = memory_limit() if max_frame_bytes is None else int(max_frame_bytes)
                require(per_frame <= limit, f"{where}: H", f"one frame needs {per_frame / 2**30:.3g}"
                        f" GiB, more than the {limit / 2**30:.3g} GiB allowed", "crop the frames")
                fields = {k: dataset(f, k, self.path) for k in REQUIRED + ("scene_info",)
                          if k in f and k != "H"}
                for k in ("laser_xyz", "sensor_xyz", "sensor_grid_format", "laser_grid_format"):
                    if k in f:
                        fields[k] = dataset(f, k, self.path)
                self.t_s = np.asarray(f["frame_t_s"][()], dtype=np.float64).reshape(-1)
                self.n_frames = int(H.shape[0])
                require(self.t_s.size == self.n_frames and self.n_frames >= 1, where,
                        f"frame_t_s has {self.t_s.size} entries for {self.n_frames} frames",
                        "write it again")
                sets = to_histograms(fields, _FrameView(H, 0), self.path)
                require(len(sets) == 1, where, f"has {len(sets)} laser points per frame",
                        "write one laser point (or one per histogram: paired) per sequence")
                require(int(np.prod(H.shape[2:])) == sets[0].n_detectors, f"{where}: H",
                        f"has shape {H.shape}: a trailing Stokes axis (polarized frames)",
                        "write each frame's first Stokes channel (S0) only")
        except InputError:
            raise
        except (OSError, RuntimeError, LookupError, ValueError, TypeError) as exc:
            raise InputError(f"{where}: incomplete or corrupted file ({type(exc).__name__}: "
                             f"{exc}). Fix: copy or write the sequence again")
        self._first, self.frame = sets[0], YTAL
        self.layout = sets[0].layout

    def __len__(self) -> int:
        return self.n_frames

    def _make(self, k, data, truths) -> SequenceFrame:
        from ...core.histograms import HistogramSet
        h = self._first
        bad = int(data.size - np.count_nonzero(np.isfinite(data)))
        require(bad == 0, f"sequence {self.path}: H[{k}]", f"{bad} values are NaN or inf",
                "replace missing bins by 0 before writing")
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
            R = f["frame_truths"] if "frame_truths" in f else None
            n_t = H.shape[1]
            for k in range(max(int(start), 0), stop):
                data = np.asarray(H[k], dtype=np.float64).reshape(n_t, -1).T
                yield self._make(k, data, None if R is None else np.asarray(R[k], float))

    def __iter__(self):
        return self.frames()

    def __getitem__(self, k: int) -> SequenceFrame:
        require(isinstance(k, (int, np.integer)) and -self.n_frames <= k < self.n_frames,
                "frame", f"index {k!r} outside 0..{self.n_frames - 1}", "pass a valid index")
        k = int(k) % self.n_frames
        return next(self.frames(k, k + 1))


def read_sequence(path, *, max_frame_bytes: int | None = None) -> Sequence:
    """Open a sequence file (or a plain y-tal capture, read as one frame) for lazy reading."""
    return Sequence(path, max_frame_bytes=max_frame_bytes)
