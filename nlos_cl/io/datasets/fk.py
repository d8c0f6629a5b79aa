"""Confocal scans as f-k migration publishes them (Lindell, Wetzstein, O'Toole, "Wave-based
non-line-of-sight imaging using fast f-k migration", ACM TOG 38(4), 2019;
github.com/computational-imaging/nlos-fk, the data from its project page): a scene folder with
`tof.mat` (variable `tofgrid`) and one or more `meas_<T>min.mat` (variable `meas`).

Facts, from the upstream README.md, demo.m and cnlos_reconstruction.m:
- `meas`: (N, N, T) photon counts, MATLAB's axes (y, x, t) (demo.m: "% y, x, t"): 512 x 512 x
  2048 for the scenes, bins of 32 ps (`bin_resolution = 32e-12`);
- `tofgrid`: (N, N) the time of flight in picoseconds to each scan point; upstream "rectifies"
  every histogram by shifting it floor(tofgrid / 32) bins earlier (circshift), so that t = 0 is
  the wall bounce, then keeps the first `crop` bins (512: cnlos_reconstruction's default);
- the scan covers a 2 m x 2 m wall (`wall_size = 2`): N points evenly over [-1, 1] m on
  each axis; the sensor is gated, so bins before the gate opens hold no counts.

Our choices (upstream does not say): row i of `meas` is the wall height z = +width .. -width
from the top (as MATLAB's images are shown), column j is x = -width .. +width; `transpose` and
`flip` change that (a target's depth does not depend on it). A rectified bin runs past the end
of the record as zeros (circshift would wrap the record's start round). The shift is whole bins,
as upstream: each histogram's t = 0 is the wall bounce to within one bin (32 ps, 4.8 mm of
range); bin 0 is t = 0 (`t0_ps` moves it).

Non-planar scans (upstream's `nonplanar` scene: a calibration.mat beside the meas file holds
`z_offset`, each scan point's offset from the plane, and `width`, the scan's full side): the
relay wall here is a plane, so each histogram gets upstream's naive correction
(nonplanar_reconstruction.m, `use_naive`: 2 floor(z_offset / (c x bin)) bins later, as if
measured on the plane; exact for a target along the wall's normal, 2 z_offset (1 - cos theta)
off at theta from it) and the scan's side comes from `width`.

Size: a 512 x 512 scan is 262,144 histograms (4.3 GB as float64). By default blocks of
`block` x `block` neighbouring scan points are summed into one histogram at their mean spot,
`block` the smallest power of two dividing N that leaves at most MAX_SIDE x MAX_SIDE
histograms, or the largest that divides N (512: 8,
64 x 64 = 4,096, a block 31 mm wide, whose paths differ by less than that); the file is read a
few bins at a time (h5py for MATLAB v7.3), so memory stays at ~CHUNK_BINS x N x N values.
A 4-D `meas` (upstream's interactive captures: frames x y x x x t, a person in a retroreflective
outfit scanned at 32 x 32 and 4 fps or 64 x 64 and 2 fps) is the `fk-interactive` format: a
sequence of such frames (`read_fk_interactive`), 1,024 bins kept (demo.m's crop for them).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.constants import SPEED_OF_LIGHT
from ...core.errors import require
from ...core.histograms import HistogramSet
from ...core.limits import require_memory
from ...core.paths import PathCalibration, TimeAxis
from ..ytal.checks import MAX_WALL_SPAN_M
from .matfile import NUMERIC, is_v73, load, variables

BIN_PS = 32.0  # cnlos_reconstruction.m: bin_resolution = 32e-12
WIDTH_M = 1.0  # demo.m: wall_size = 2 (m), width = wall_size / 2
CROP_BINS = 512  # cnlos_reconstruction.m: crop = 512
MAX_SIDE = 64  # histograms per side after the default block sum (at most 4,096)
CHUNK_BINS = 16  # record bins read per pass
INTERACTIVE_CROP_BINS = 1024  # demo.m: "crop = 1024; % crop measurements to 1024 bins"
INTERACTIVE_FPS = {32: 4.0, 64: 2.0}  # README: "32 x 32 (4 fps), 64 x 64 (2 fps)"


def fk_files(path) -> tuple[Path, Path]:
    """(meas file, tof file): `path` is a meas_*.mat file (its tof.mat, or tof_<suffix>.mat for
    meas_<suffix>.mat, beside it) or a folder holding exactly one meas_*.mat."""
    path = Path(path)
    if path.is_dir():
        found = sorted(path.glob("meas*.mat"))
        require(len(found) == 1, f"dataset {path}", f"holds {len(found)} meas*.mat files "
                f"({', '.join(p.name for p in found) or 'none'})", "pass one of them: "
                "nlos-cl convert FOLDER/meas_10min.mat --out F.h5")
        path = found[0]
    suffix = path.stem[len("meas"):]
    tof = next((p for p in (path.with_name(f"tof{suffix}.mat"), path.with_name("tof.mat"))
                if p.is_file()), None)
    require(tof is not None, f"dataset {path}", f"has no tof{suffix}.mat or tof.mat beside it "
            "(the per-point time of flight that rectifies the histograms)", "keep the scene's "
            "folder as downloaded")
    return path, tof


def read_fk(path, *, dt_ps: float = BIN_PS, t0_ps: float = 0.0, width_m: float | None = None,
            crop_bins: int | None = None, block: int | None = None, transpose: bool = False,
            flip: str = "") -> HistogramSet:
    """An f-k scene (a meas_*.mat and its tof.mat) as a confocal HistogramSet: rectified by
    tofgrid, the first `crop_bins` bins (None: CROP_BINS, or the record if shorter), blocks of
    `block` x `block` scan points summed (None: the default, see the module docstring)."""
    scan = _Scan(path, 3, dt_ps, t0_ps, width_m, CROP_BINS if crop_bins is None else crop_bins,
                 block, flip, clip=crop_bins is None)
    with _Chunks(scan.path, scan.n, 3) as chunks:
        return scan.histograms(_rectified_blocks(scan, chunks), transpose)


def read_fk_interactive(path, *, dt_ps: float = BIN_PS, t0_ps: float = 0.0,
                        width_m: float | None = None, crop_bins: int | None = None,
                        block: int | None = None, transpose: bool = False, flip: str = "",
                        fps: float | None = None) -> tuple[list, dict]:
    """f-k's interactive captures (meas_32.mat / meas_64.mat with tof_32.mat / tof_64.mat: a
    4-D meas, frames x y x x x t) as (frames, metadata): frame k a confocal HistogramSet
    rectified like a scene (`read_fk`), at t = k / fps (default: the README's 4 fps for
    32 x 32 scans, 2 fps for 64 x 64; other sizes need fps); crop_bins None:
    INTERACTIVE_CROP_BINS, or the record if shorter."""
    scan = _Scan(path, 4, dt_ps, t0_ps, width_m, INTERACTIVE_CROP_BINS if crop_bins is None
                 else crop_bins, block, flip, clip=crop_bins is None)
    if fps is None:
        fps = INTERACTIVE_FPS.get(scan.n)
        require(fps is not None, "fps", f"is not known for a {scan.n} x {scan.n} interactive "
                "scan (the README gives 4 fps for 32 x 32, 2 fps for 64 x 64)", "pass --fps")
    require(np.isfinite(fps) and fps > 0, "fps", f"must be positive, got {fps}", "pass e.g. 4")
    side = scan.n // scan.block
    require_memory(f"{scan.path}: meas", 8.0 * scan.n_frames * side * side * scan.crop,
                   f"{scan.n_frames} frames of {side} x {side} histograms", "pass --block "
                   "or --crop-bins to keep fewer values")
    with _Chunks(scan.path, scan.n, 4) as chunks:
        frames = [(k / fps, scan.histograms(_rectified_blocks(scan, chunks, k), transpose))
                  for k in range(scan.n_frames)]
    return frames, {"fps": float(fps), "scan_points": scan.n, "block": scan.block,
                    "crop_bins": scan.crop}


class _Scan:
    """A meas file's declared geometry and its tofgrid's whole-bin shifts, checked."""

    def __init__(self, path, ndim, dt_ps, t0_ps, width_m, crop_bins, block, flip, clip=False):
        require(np.isfinite(dt_ps) and dt_ps > 0, "dt_ps", f"must be positive, got {dt_ps}",
                f"pass e.g. {BIN_PS:g}")
        require(width_m is None or (np.isfinite(width_m) and width_m > 0), "width_m",
                f"must be positive, got {width_m}", f"pass e.g. {WIDTH_M:g}")
        require(np.isfinite(t0_ps), "t0_ps", f"must be finite, got {t0_ps}", "pass e.g. 0")
        require(flip in ("", "x", "z", "xz", "zx"), "flip", f"must be x, z or xz, got "
                f"{flip!r}", "pass --flip x, z or xz")
        self.path, tof_path = fk_files(path)
        declared = variables(self.path)
        require("meas" in declared, f"{self.path}: meas", f"is missing (the file holds "
                f"{sorted(declared)})", "pass the dataset's own, unmodified file")
        shape, kind = declared["meas"]
        require(kind in NUMERIC, f"{self.path}: meas", f"is declared {kind}, not numeric",
                "pass the dataset's own, unmodified file")
        other = {3: "a scene's 3-D meas: --format fk", 4: "an interactive capture's 4-D meas "
                 "(frames x y x x x t): --format fk-interactive"}
        require(len(shape) == ndim or len(shape) not in other, f"{self.path}: meas",
                f"is {len(shape)}-D {shape}", f"read {other.get(len(shape))}")
        scan = shape[-3:]
        require(len(shape) == ndim and scan[0] == scan[1] and scan[2] >= 2, f"{self.path}: "
                "meas", f"is {shape}, expected {'(F, ' if ndim == 4 else '('}N, N, T): a "
                "square scan of histograms", "pass the dataset's own, unmodified file")
        self.ndim, self.n_frames = ndim, int(shape[0]) if ndim == 4 else 1
        self.n, self.n_t = int(scan[0]), int(scan[2])
        n, n_t = self.n, self.n_t
        crop_bins = min(crop_bins, n_t) if clip else crop_bins  # a default: the record at most
        require(int(crop_bins) == crop_bins and 2 <= crop_bins <= n_t, "crop_bins", f"must be "
                f"a bin count in 2..{n_t}, got {crop_bins}", f"pass e.g. {min(CROP_BINS, n_t)}")
        self.crop = int(crop_bins)
        block = _default_block(n) if block is None else block
        require(int(block) == block and block >= 1 and n % block == 0, "block", f"must divide "
                f"the scan's {n} points per side, got {block}", f"pass e.g. {_default_block(n)}")
        self.block = int(block)
        tof = load(tof_path, "tofgrid", 2)
        require(tof.shape == (n, n), f"{tof_path}: tofgrid", f"is {tof.shape}, the scan {n} x "
                f"{n}", "pass the tof.mat of the same scene")
        _require_picoseconds(tof, tof_path)
        self.shift = np.floor(tof / dt_ps).astype(np.int64)
        require(bool(np.all((self.shift >= 0) & (self.shift < n_t))), f"{tof_path}: tofgrid",
                f"holds times outside the record (0 .. {n_t * dt_ps:g} ps)", "pass the tof.mat "
                "of the same scene")
        later, half = _nonplanar(self.path, n, dt_ps)
        if later is not None:  # the naive correction: each histogram that many bins later
            self.shift = self.shift - later
            lost = int(np.count_nonzero((self.shift >= n_t) | (self.shift + self.crop <= 0)))
            require(lost == 0, f"{self.path.with_name('calibration.mat')}: z_offset", f"moves "
                    f"{lost} of {n * n} histograms wholly out of the record (they would be "
                    "zeros)", "pass the calibration.mat of the same scene, z_offset in metres")
        self.width_m = width_m if width_m is not None else half
        self.dt_ps, self.t0_ps, self.flip = dt_ps, t0_ps, flip

    def histograms(self, cube, transpose) -> HistogramSet:
        """The (side, side, crop) rectified blocks as a confocal HistogramSet on the wall."""
        if transpose:
            cube = cube.transpose(1, 0, 2)
        side = self.n // self.block
        # a block's mean position: the mean of its points' evenly spaced coordinates
        u = np.linspace(-self.width_m, self.width_m, self.n).reshape(side, self.block).mean(1)
        # rows from the top, columns along x (after `transpose`, of the swapped cube)
        x_of_j, z_of_i = u.copy(), u[::-1].copy()
        x_of_j = x_of_j[::-1] if "x" in self.flip else x_of_j
        z_of_i = z_of_i[::-1] if "z" in self.flip else z_of_i
        z, x = np.meshgrid(z_of_i, x_of_j, indexing="ij")  # row k = (i, j), as reshape does
        spots = np.column_stack([x.ravel(), np.zeros(x.size), z.ravel()])
        axis = TimeAxis(self.t0_ps * 1e-12, self.dt_ps * 1e-12, self.crop)
        return HistogramSet(cube.reshape(side * side, self.crop), axis, spots, spots,
                            PathCalibration(SPEED_OF_LIGHT, [0.0]))


def _nonplanar(meas_path, n, dt_ps):
    """(bins (N, N) or None, the scan's half side, m): for a non-planar scan (a calibration.mat
    beside the meas file with `z_offset` (N, N), m, and `width`, the scan's full side:
    nonplanar_reconstruction.m's x = linspace(-width / 2, width / 2)) upstream's naive
    correction, each histogram 2 floor(z_offset / (c x bin)) bins later (its `use_naive`
    circshift), as if measured on the plane; (None, WIDTH_M) for a planar scene."""
    path = meas_path.with_name("calibration.mat")
    held = variables(path) if path.is_file() else {}
    if "z_offset" not in held:
        return None, WIDTH_M
    z_offset = load(path, "z_offset", 2)
    require(z_offset.shape == (n, n), f"{path}: z_offset", f"is {z_offset.shape}, the scan "
            f"{n} x {n}", "pass the calibration.mat of the same scene")
    half = 0.5 * float(load(path, "width", 2).ravel()[0]) if "width" in held else WIDTH_M
    require(np.isfinite(half) and 0 < half <= MAX_WALL_SPAN_M / 2, f"{path}: width",
            f"must be the scan's side in metres (at most {MAX_WALL_SPAN_M:g}), got {2 * half:g}"
            + (": that looks like millimetres" if half > MAX_WALL_SPAN_M / 2 else ""),
            "store width in metres (divide millimetres by 1000)")
    deepest = float(np.abs(z_offset).max())
    require(deepest <= 2 * half, f"{path}: z_offset", f"reaches {deepest:.4g} m off the plane, "
            f"more than the scan's {2 * half:.4g} m side: that looks like millimetres",
            "store z_offset in metres (divide millimetres by 1000)")
    bins = 2 * np.floor(z_offset / (SPEED_OF_LIGHT * dt_ps * 1e-12)).astype(np.int64)
    return bins, half


# a tofgrid time is the device -> wall -> device path of a scan point: f-k's scenes are ~1 m
# away (3000-6000 ps); under 0.2 m of path no galvo scans a wall
MIN_TOF_PATH_M = 0.2


def _require_picoseconds(tof, tof_path) -> None:
    """tofgrid in picoseconds, as upstream stores it: its median path at least MIN_TOF_PATH_M
    (nanoseconds, microseconds or zeros would shift nothing, and the capture would keep the
    wall's own return); the unit it looks like is named."""
    median = float(np.median(tof))
    path_m = SPEED_OF_LIGHT * median * 1e-12
    if path_m >= MIN_TOF_PATH_M:
        return
    units = {"nanoseconds": 1e3, "microseconds": 1e6, "seconds": 1e12}
    unit = next((u for u, k in units.items()
                 if MIN_TOF_PATH_M <= SPEED_OF_LIGHT * median * k * 1e-12 <= 1e3), None)
    require(False, f"{tof_path}: tofgrid", f"its median {median:.4g} ps is {path_m:.3g} m of "
            f"path to the wall, less than the {MIN_TOF_PATH_M:g} m of any scan"
            + (f": that looks like {unit}" if unit else " (no time of flight)"),
            "store tofgrid in picoseconds, as f-k's tof.mat does"
            + (f" (multiply {unit} by {units[unit]:g})" if unit else ""))


def _default_block(n: int) -> int:
    block = 1
    while n // block > MAX_SIDE and n % (2 * block) == 0:
        block *= 2
    return block


def _rectified_blocks(scan, chunks, frame=None) -> np.ndarray:
    """(side, side, crop): meas[(frame,) i, j, shift[i, j] + k] summed over each block, read
    CHUNK_BINS record bins at a time (only the bins some histogram keeps)."""
    n, n_t, crop, block, shift = scan.n, scan.n_t, scan.crop, scan.block, scan.shift
    side = n // block
    # a chunk's values, times and indices (~6 arrays of it), and the sums twice (bincount's)
    require_memory(f"{scan.path}: meas", 8.0 * 6 * CHUNK_BINS * n * n + 16.0 * side * side *
                   crop, f"rectifying {n} x {n} histograms", "pass --block or --crop-bins to "
                   "keep fewer values")
    cell = ((np.arange(n)[:, None] // block) * side + np.arange(n)[None, :] // block).ravel()
    flat_shift = shift.ravel()
    out = np.zeros(side * side * crop)
    first, last = max(int(shift.min()), 0), min(int(shift.max()) + crop, n_t)
    for t0 in range(first, last, CHUNK_BINS):
        t1 = min(t0 + CHUNK_BINS, last)
        values = chunks.read(t0, t1, frame)  # (t1 - t0, n * n), point index i * n + j
        k = np.arange(t0, t1)[:, None] - flat_shift[None, :]
        keep = (k >= 0) & (k < crop)
        if not keep.any():
            continue
        index = (cell[None, :] * crop + k)[keep]
        out += np.bincount(index, values[keep], minlength=out.size)
    return out.reshape(side, side, crop)


class _Chunks:
    """meas[(frame,) :, :, t0:t1] as (t1 - t0, N * N) float64 rows (point index i * N + j),
    from a v7.3 file through h5py (a slab of the record's leading axis: MATLAB's last) or,
    from older .mat files, from the array scipy.io loads once (its size checked first), for
    every frame."""

    def __init__(self, path, n, ndim):
        self.path, self.n, self.ndim = path, n, ndim
        self._file = self._array = None

    def __enter__(self):
        if is_v73(self.path):
            import h5py
            self._file = h5py.File(self.path, "r")
            self._dataset = self._file["meas"]  # h5py: MATLAB's axes reversed
            from ...core import gate
            from ..hdf5_gate import check_chunks
            # a deflate chunk inflates to its stream's end whatever it declares: bounded
            # first, within what rectifying leaves of the budget (as every v7.3 read)
            check_chunks(self._dataset, f"{self.path}: meas", gate.budget(None)[0] - 48.0 *
                         CHUNK_BINS * self.n ** 2, 0.0, "pass the dataset's own, unmodified "
                         "file")
        else:
            self._array = load(self.path, "meas", self.ndim)
        return self

    def read(self, t0, t1, frame=None) -> np.ndarray:
        if self._file is not None:  # (t, j, i[, frame]) -> rows of points i * N + j
            part = self._dataset[t0:t1] if frame is None else self._dataset[t0:t1, :, :, frame]
            part = np.asarray(part, dtype=np.float64).transpose(0, 2, 1)
        else:
            cube = self._array if frame is None else self._array[frame]
            part = np.moveaxis(cube[:, :, t0:t1], 2, 0)
        part = part.reshape(t1 - t0, self.n * self.n)
        require(bool(np.all(np.isfinite(part))), f"{self.path}: meas", "contains NaN or inf",
                "pass the dataset's own, unmodified file")
        return part

    def __exit__(self, *exc):
        if self._file is not None:
            self._file.close()
        return False
