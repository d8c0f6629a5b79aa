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
- stage geometry: lateral offset x - 0.5 m; depth: the object plane 0.64 m from the spot at its
  closest (z_offset) over a z travel of 0.15 m (z_range); the spot 1.13 m above the floor
  (y_offset), the object's sampling positions at that height (Demo.py's sampling_coordinates:
  y = y_offset), so the height difference is 0 and y_offset drops out. Which end of the z
  travel is the closest is not stated; Demo.py puts its object grid at z_offset + z_range =
  0.79 m, and the data decide: the peak range correlates with the depth 0.79 - zpos (0.94 to
  0.96 on E, K, Y) and not with 0.64 + zpos (-0.07 to 0.28). So the range to the object is
  r = sqrt((xpos - 0.5)^2 + (0.79 - zpos)^2), stored per frame as truth metadata
  (`stage_range_m`), with the stage positions.

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
from ...core.limits import require_memory
from ...core.paths import PathCalibration, TimeAxis

BIN_PS = 16.0  # Demo.py: bin_resolution_t = 16e-12
N_BINS = 768  # Demo.py: n_t, the bins kept from time zero
GATE_BINS = 260  # Demo.py: clip_until, the cropped bins zeroed (the wall's own return)
X_CENTRE_M = 0.5  # Demo.py: x_offset = -x_range / 2, x_range = 1
Z_FAR_M = 0.64 + 0.15  # Demo.py: z_offset + z_range, the object's depth at zpos = 0
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
    xpos, zpos = (_h5(scans[0], n).ravel() for n in ("xpos", "zpos"))
    n = data.shape[0]
    require(data.ndim == 2 and len(xpos) == n and len(zpos) == n and len(background) ==
            data.shape[1], f"{scans[0]}", f"data {data.shape}, xpos {xpos.shape}, zpos "
            f"{zpos.shape} and the background {background.shape} do not match",
            "pass the dataset's own, unmodified files")
    zero = int(np.argmax(direct))
    require(zero + N_BINS <= data.shape[1], f"{folder / 'direct_after.mat'}", f"peaks at bin "
            f"{zero}, too late for {N_BINS} bins after it", "pass the dataset's own files")
    crop, bg = data[:, zero:zero + N_BINS], background[zero:zero + N_BINS]
    scale = crop[:, :GATE_BINS].sum(axis=1) / max(bg[:GATE_BINS].sum(), 1.0)
    signal = crop - scale[:, None] * bg[None, :]
    signal[:, :GATE_BINS] = 0.0
    axis = TimeAxis(0.0, dt_ps * 1e-12, N_BINS)
    spot = np.zeros((1, 3))
    frames = [(k / fps, HistogramSet(signal[k:k + 1], axis, spot, spot,
                                     PathCalibration(SPEED_OF_LIGHT, [0.0]))) for k in range(n)]
    ranges = np.hypot(xpos - X_CENTRE_M, Z_FAR_M - zpos)
    return frames, {"fps": float(fps), "stage_range_m": ranges.tolist(),
                    "xpos_m": xpos.tolist(), "zpos_m": zpos.tolist(), "time_zero_bin": zero,
                    "background_scale": scale.tolist(), "gate_bins": GATE_BINS,
                    "truth": "stage_range_m = sqrt((xpos - 0.5)^2 + (0.79 - zpos)^2), from "
                             "the stage (Demo.py's geometry)"}


def _h5(path, name) -> np.ndarray:
    """A MATLAB v7.3 variable as float64 (h5py: MATLAB's axes reversed), its declared size
    checked against memory first."""
    import h5py

    from ..safe_write import require_file
    from ..ytal.checks import unreadable
    from ..ytal.fields import check_storage
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
        require(name in f and isinstance(f[name], h5py.Dataset), f"{path}: {name}",
                f"is missing (it holds {sorted(f)})", "pass the dataset's own, unmodified file")
        d = f[name]
        require_memory(f"{path}: {name}", 16.0 * float(np.prod(d.shape, dtype=np.float64)),
                       f"reading {name} {d.shape}", "read it on a machine with more memory")
        try:
            value = np.asarray(d[()], dtype=np.float64)
        except (OSError, RuntimeError, ValueError, TypeError) as exc:
            raise unreadable(exc, path, name, "MATLAB file") from None
    require(bool(np.all(np.isfinite(value))), f"{path}: {name}", "contains NaN or inf",
            "pass the dataset's own, unmodified file")
    return value

