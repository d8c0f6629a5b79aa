"""Keyhole scans (Metzler, Lindell, Wetzstein, "Keyhole Imaging: Non-Line-of-Sight Imaging and
Tracking of Moving Objects Along a Single Optical Path", IEEE TCI 7, 2021;
github.com/computational-imaging/KeyholeImaging, captured_data/{E,K,Y}/): one folder per
object with scan_*.mat, direct_after.mat and LongExpNoObject_after.mat (MATLAB v7.3 = HDF5).

Facts, from the upstream Demo.py (as summarised in ../shared/realdata/keyhole/README.md):
- ONE wall spot: the laser point is the detection point (confocal), path = 2 |spot - p|;
- `data` (F, 65536) one histogram per exposure, 16 ps bins; `xpos`, `zpos` (F, 1) the stage's
  position at that exposure (m); h5py gives MATLAB's arrays transposed, so rows are exposures;
- time zero: the argmax of `direct_after` (the wall's direct return; about bin 630); the demo
  keeps the 768 bins from there and zeroes the first 260 of them (the wall's own tail);
- background: the demo subtracts `LongExpNoObject_after` unscaled. Ours scales it per frame
  by the ratio of the frame's counts to the background's in those first 260 cropped bins,
  where the object cannot be (its closest path, 2 x 0.64 m, is bin 267): the ratio is 1.00 within
  1 % on E, K and Y, so this is the demo's subtraction, and stays right for an exposure of
  another length;
- time zero drifts during a scan: `direct_before.mat` (taken before it) peaks earlier than
  `direct_after.mat` (E 5.0 bins, K 1.2, Y 2.6 bins at the half-height of their rise; the
  no-object exposures' gate edges move alike, E 792.5 -> 798.5). Frame k of F is cropped from
  the time zero interpolated linearly between the two (to the nearest bin; a sequence has one
  time axis), so every frame's bin 0 is its own wall return; without direct_before, no drift;
- the wall return's peak bin is centred on t = 0 (the time axis starts half a bin earlier),
  nlos_cl's convention that the pulse's peak is at hidden path 0;
- stage geometry, from Demo.py's forward model (utils.Sample_Lambertian: the range is
  |sampling point - voxel|): the sampling point (the spot, in the object's frame) is
  (xpos - 0.5, y_offset = 1.13, zpos), the object's voxels lie in the plane z = z_offset +
  z_range = 0.79 m, at heights 0.5 .. 1.1 m (the default closeup grid: object_y_offset 0.5,
  object_scale 0.6) around lateral 0. The range from the spot to the grid's centre
  (0, 0.8, 0.79) is r = sqrt((xpos - 0.5)^2 + 0.33^2 + (0.79 - zpos)^2), stored per frame as
  truth metadata (`stage_range_m`) with the stage positions. The data agree on the depth's
  sign: the peak range correlates with 0.79 - zpos (0.94 to 0.96 on E, K, Y) and not with
  0.64 + zpos (-0.07 to 0.28). Where on the grid each letter's bright part sits is not
  documented (Demo.py reconstructs it): a few cm of it is left in any range.

With one spot only the range is observable: nlos_cl's locator refuses a single detector
(nlos_cl.io.ytal.frames.require_locatable). A range per frame (half the hidden path at the peak
of the Gauss-filtered histogram) needs the Gauss filter of nlos_cl.localization, a later layer
than io, so it does not live here (docs/architecture.md).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.constants import SPEED_OF_LIGHT
from ...core.errors import require
from ...core.histograms import HistogramSet
from ...core.limits import MAX_FRAMES, require_count
from ...core.paths import PathCalibration, TimeAxis

BIN_PS = 16.0  # Demo.py: bin_resolution_t = 16e-12
N_BINS = 768  # Demo.py: n_t, the bins kept from time zero
GATE_BINS = 260  # Demo.py: clip_until, the cropped bins zeroed (the wall's own return)
X_CENTRE_M = 0.5  # Demo.py: x_offset = -x_range / 2, x_range = 1
Z_FAR_M = 0.64 + 0.15  # Demo.py: z_offset + z_range, the object's depth at zpos = 0
# Demo.py: the spot's height y_offset = 1.13 m above the floor; the object grid (closeup, the
# default) spans object_y_offset 0.5 .. 0.5 + object_scale 0.6 m: its centre is 0.33 m lower.
HEIGHT_BELOW_SPOT_M = 1.13 - (0.5 + 0.6 / 2)
FPS = 1.0  # not documented upstream: frame k is at k s (pass --fps)


def read_keyhole(folder, *, dt_ps: float = BIN_PS, fps: float = FPS) -> tuple[list, dict]:
    """A Keyhole object folder as (frames, metadata): frames (t_s, HistogramSet) pairs of one
    confocal histogram at the spot (0, 0, 0), metadata {"stage_range_m", "xpos_m", "zpos_m",
    "time_zero_bin", "background_scale", ...}."""
    folder = Path(folder)
    for name, value, default in (("dt_ps", dt_ps, BIN_PS), ("fps", fps, FPS)):
        require(np.isfinite(value) and value > 0, name, f"must be positive, got {value}",
                f"pass e.g. {default:g}")
    require(folder.is_dir(), f"dataset {folder}", "is not a folder", "pass a Keyhole object "
            "folder (scan_*.mat, direct_after.mat, LongExpNoObject_after.mat)")
    scans = sorted(folder.glob("scan_*.mat"))
    require(len(scans) == 1, f"dataset {folder}", f"holds {len(scans)} scan_*.mat files",
            "pass a folder with exactly one scan")
    direct = _h5(folder / "direct_after.mat", "direct_after").ravel()
    background = _h5(folder / "LongExpNoObject_after.mat", "LongExpNoObject_after").ravel()
    data = _h5(scans[0], "data")
    require(data.ndim == 2 and data.shape[0] >= 1 and data.shape[1] > N_BINS,
            f"{scans[0]}: data", f"is {data.shape}, expected (frames, bins): one histogram of "
            f"more than {N_BINS} bins per exposure, at least one", "pass the dataset's own, "
            "unmodified scan file")
    require_count(f"{scans[0]}: data", data.shape[0], MAX_FRAMES, "frames", "split the scan")
    xpos, zpos = (_h5(scans[0], n).ravel() for n in ("xpos", "zpos"))
    n = data.shape[0]
    require(len(xpos) == n and len(zpos) == n and len(background) ==
            data.shape[1] == len(direct), f"{scans[0]}", f"data {data.shape}, xpos "
            f"{xpos.shape}, zpos {zpos.shape}, the background {background.shape} and the "
            f"direct return {direct.shape} do not match", "pass the dataset's own, unmodified "
            "files")
    zero = int(np.argmax(direct))
    drift = _time_zero_drift(folder, direct, n)
    starts = zero + np.round(drift).astype(int)  # frame k's own wall return, to the bin
    require(starts.min() >= 0 and starts.max() + N_BINS <= data.shape[1],
            f"{folder / 'direct_after.mat'}", f"peaks at bin {zero} (drift {drift[0]:+.1f} "
            f"bins), too near the record's ends for {N_BINS} bins after it",
            "pass the dataset's own files")
    rows = np.arange(n)[:, None]
    crop = data[rows, starts[:, None] + np.arange(N_BINS)[None, :]]
    bg = background[zero:zero + N_BINS]
    scale = crop[:, :GATE_BINS].sum(axis=1) / max(bg[:GATE_BINS].sum(), 1.0)
    signal = crop - scale[:, None] * bg[None, :]
    signal[:, :GATE_BINS] = 0.0
    axis = TimeAxis(-0.5 * dt_ps * 1e-12, dt_ps * 1e-12, N_BINS)  # bin 0's centre at t = 0
    spot = np.zeros((1, 3))
    frames = [(k / fps, HistogramSet(signal[k:k + 1], axis, spot, spot,
                                     PathCalibration(SPEED_OF_LIGHT, [0.0]))) for k in range(n)]
    ranges = stage_range_m(xpos, zpos)
    return frames, {"fps": float(fps), "stage_range_m": ranges.tolist(),
                    "xpos_m": xpos.tolist(), "zpos_m": zpos.tolist(), "time_zero_bin": zero,
                    "time_zero_drift_bins": [round(float(d), 3) for d in drift],
                    "background_scale": scale.tolist(), "gate_bins": GATE_BINS,
                    "truth": "stage_range_m = sqrt((xpos - 0.5)^2 + 0.33^2 + (0.79 - zpos)^2): "
                             "the range to the centre of Demo.py's object grid"}


def stage_range_m(xpos, zpos, lateral_m: float = 0.0) -> np.ndarray:
    """The range (m) from the spot to a point of the object plane at the stage position
    (xpos, zpos): the object grid's centre, or `lateral_m` beside it (where a letter's bright
    middle may sit: the dataset does not say)."""
    xpos, zpos = np.asarray(xpos, dtype=np.float64), np.asarray(zpos, dtype=np.float64)
    return np.sqrt((xpos - X_CENTRE_M - lateral_m) ** 2 + HEIGHT_BELOW_SPOT_M ** 2
                   + (Z_FAR_M - zpos) ** 2)


def _time_zero_drift(folder: Path, after: np.ndarray, n: int) -> np.ndarray:
    """(n,) bins by which frame k's time zero precedes direct_after's: the before and after
    returns' difference, linear in the frame index (0 without direct_before.mat). Measured at
    the half height of each return's rise: their peaks are clipped at 65,535 counts."""
    path = folder / "direct_before.mat"
    if not path.is_file():
        return np.zeros(n)
    before = _h5(path, "direct_before").ravel()
    require(len(before) == len(after), f"{path}", f"holds {len(before)} bins, direct_after "
            f"{len(after)}", "pass the dataset's own, unmodified files")
    shift = _rise_bin(before) - _rise_bin(after)
    return shift * (1.0 - np.arange(n) / max(n - 1, 1))


def _rise_bin(direct: np.ndarray) -> float:
    """Where the return first reaches half its peak (interpolated bin)."""
    k = int(np.argmax(direct))
    half = 0.5 * direct[k]
    below = np.flatnonzero(direct[:k + 1] < half)
    require(below.size > 0 and direct[k] > 0, "direct return", "has no rise before its peak",
            "pass the dataset's own direct_before.mat / direct_after.mat")
    j = int(below[-1])
    return j + float((half - direct[j]) / (direct[j + 1] - direct[j]))


def _h5(path, name) -> np.ndarray:
    """A MATLAB v7.3 variable as float64 in MATLAB's axis order (matfile.h5_array: its storage
    and declared size checked first)."""
    import h5py

    from ..safe_write import require_file
    from ..ytal.checks import unreadable
    from ..ytal.fields import check_storage
    from .matfile import h5_array
    require_file(path, f"{path}", "pass the dataset's own folder")
    try:
        f = h5py.File(path, "r")
    except BlockingIOError as exc:
        raise unreadable(exc, path, what="MATLAB file") from None
    except OSError as exc:
        require(False, f"{path}", f"is not a MATLAB v7.3 (HDF5) file ({exc})", "download it "
                "again")
    with f:
        check_storage(f, path, "MATLAB file")  # links would read other files
        value = h5_array(f, name, path).T  # h5py's order, as the reader below expects
    require(bool(np.all(np.isfinite(value))), f"{path}: {name}", "contains NaN or inf",
            "pass the dataset's own, unmodified file")
    return value
