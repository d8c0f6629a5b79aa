"""CC-SOCR folders (Liu et al., "Non-line-of-sight imaging with arbitrary illumination and
detection pattern", Nature Communications 14:3230, 2023; github.com/hy520484/general-NLOS,
public_data/demo_code/data/<scene>/<pattern>/): sub_Sig.mat, C_i.mat, C_d.mat.

Facts, from the upstream setup script `experimental_setup.m` (as summarised in
../shared/realdata/ccsocr-figure4/README.md):
- sub_Sig (N, T) photon counts in 16 ps bins, one row per scanned laser point;
- C_i (N, 3): each row's illuminated wall point, C_d (N, 3): its detection point, as grid
  indices (depth, a, b) -> metres (i0 * c * 16 ps, i1 * 0.01 m, i2 * 0.01 m); the relay wall is
  depth = 0;
- time 0 is the wall bounce (the first and last legs are excluded): a hidden point v lands in
  bin (|v - laser_i| + |v - detection point|) / (c * 16 ps), so bin k starts at t = k * 16 ps.
Ours: a paired set ("N lasers + one detector"): laser_spot (N, 3) the C_i points, detector_spots
the C_d points, hidden path = c t. Depth is our y; (a, b) -> (x, z) = (-a, b), the proper
rotation, so that the y-tal file's (X, Y, Z) = (a, b, depth) are CC-SOCR's own metres.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.constants import SPEED_OF_LIGHT
from ...core.errors import require
from ...core.histograms import HistogramSet
from ...core.paths import PathCalibration, TimeAxis
from .matfile import load

BIN_PS = 16.0  # experimental_setup.m: 16 ps bins


GRID_M = 0.01  # experimental_setup.m: one wall index is 1 cm


def read_ccsocr(folder, *, dt_ps: float = BIN_PS, t0_ps: float = 0.0, grid_m: float = GRID_M
                ) -> HistogramSet:
    """A CC-SOCR pattern folder as a paired HistogramSet. dt_ps: bin width; t0_ps: the time of
    bin 0's start after the wall bounce; grid_m: metres per wall index."""
    folder = Path(folder)
    require(folder.is_dir(), f"dataset {folder}", "is not a folder", "pass the folder that "
            "holds sub_Sig.mat, C_i.mat and C_d.mat")
    for name, value in (("dt_ps", dt_ps), ("grid_m", grid_m)):
        require(np.isfinite(value) and value > 0, name, f"must be positive, got {value}",
                f"pass e.g. {BIN_PS if name == 'dt_ps' else GRID_M}")
    require(np.isfinite(t0_ps), "t0_ps", f"must be finite, got {t0_ps}", "pass e.g. 0")
    counts = load(folder / "sub_Sig.mat", "sub_Sig", 2)
    lasers, detectors = (wall_points(load(folder / f"{n}.mat", n, 2), folder / f"{n}.mat", n,
                                     grid_m) for n in ("C_i", "C_d"))
    n = counts.shape[0]
    for name, pts in (("C_i", lasers), ("C_d", detectors)):
        require(len(pts) == n, f"{folder / (name + '.mat')}: {name}", f"has {len(pts)} rows "
                f"but sub_Sig has {n} histograms", "pass the three files of one pattern")
    axis = TimeAxis(t0_ps * 1e-12, dt_ps * 1e-12, counts.shape[1])
    return HistogramSet(counts, axis, detectors, lasers, PathCalibration(SPEED_OF_LIGHT, [0.0]))


def wall_points(indices, path, name, grid_m) -> np.ndarray:
    """(N, 3) wall indices (depth, a, b) -> internal metres (-a, 0, b) * grid_m."""
    require(indices.shape[1:] == (3,), f"{path}: {name}", f"has shape {indices.shape}, "
            "expected (N, 3) grid indices (depth, a, b)", "pass the dataset's own file")
    require(bool(np.all(indices[:, 0] == 0)), f"{path}: {name}", "has points off the relay "
            "wall (depth index != 0)", "pass wall points (CC-SOCR's wall is depth = 0)")
    return np.column_stack([-indices[:, 1], np.zeros(len(indices)), indices[:, 2]]) * grid_m
