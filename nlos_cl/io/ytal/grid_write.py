"""Confocal scans on a regular rectangular grid (LCT, f-k, a confocal CC-SOCR pattern) written
as y-tal writes its own scans (tal.render: H_format T_Sx_Sy, H (T, Sx, Sy), sensor and laser
grids X_Y_3 with X increasing along the first grid axis and Y along the second), so that
y-tal's grid reconstructions (tal.reconstruct.fk, pf_dev's convolutions, tal.plot.xy) take
the file as it is. Whether a set is such a grid is decided from its spots alone (scan_grid);
capture.write_capture and sequence.write_sequence write such a set so, anything else flat
(T_Si, N_3).

Reading the file back (capture.read_capture) gives the same histograms at the same spots, in
the grid's order: row i * Sy + j is grid cell (i, j)."""
from __future__ import annotations

import io
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ...core.histograms import HistogramSet
from .frames import SAME_SPOT_M, to_ytal

# A spot may sit this fraction of the grid step off its grid line (and off the wall plane) and
# still be a grid point: float32 files and linspace grids are exact to ~1e-6 of a step, while
# a grid missing a column, or a jittered or rotated scan, is off by a large part of one.
STEP_TOLERANCE = 0.01


@dataclass(frozen=True)
class ScanGrid:
    """shape (Sx, Sy); order[i * Sy + j]: the set's row at grid cell (i, j)."""

    shape: tuple
    order: np.ndarray


def scan_grid(h: HistogramSet) -> ScanGrid | None:
    """The set's confocal grid in the y-tal file's (X, Y), or None where its spots are not one:
    every laser spot on its detector spot (within SAME_SPOT_M), at least 2 x 2 points, each on
    one cell of an evenly spaced X x Y lattice in the wall plane Z = const (STEP_TOLERANCE of a
    step), every cell once."""
    n = h.n_detectors
    if not h.paired or n < 4 or not np.allclose(h.laser_spots, h.detector_spots, rtol=0,
                                                 atol=SAME_SPOT_M):
        return None
    p = to_ytal(h.detector_spots)
    xs, ys = _ticks(p[:, 0]), _ticks(p[:, 1])
    if xs is None or ys is None or xs[1] * ys[1] != n:
        return None
    if np.ptp(p[:, 2]) > STEP_TOLERANCE * min(xs[2], ys[2]):
        return None
    cell = xs[0] * ys[1] + ys[0]
    if np.unique(cell).size != n:
        return None
    order = np.empty(n, dtype=int)
    order[cell] = np.arange(n)
    return ScanGrid((xs[1], ys[1]), order)


def _ticks(values):
    """(each value's index on an evenly spaced axis, the axis' length, its step), or None where
    the values are not on one such axis of at least 2 ticks (ticks split at gaps over half the
    largest gap; then every value must sit within STEP_TOLERANCE of a step of its tick)."""
    v = np.sort(values)
    gaps = np.diff(v)
    if gaps.size == 0 or gaps.max() <= 0:
        return None
    starts = np.concatenate([[0], np.flatnonzero(gaps > 0.5 * gaps.max()) + 1])
    centres = np.add.reduceat(v, starts) / np.diff(np.append(starts, v.size))
    count = centres.size
    step = (centres[-1] - centres[0]) / (count - 1)
    index = np.rint((values - centres[0]) / step).astype(int)
    off = np.abs(values - (centres[0] + index * step))
    if index.min() != 0 or index.max() != count - 1 or off.max() > STEP_TOLERANCE * step:
        return None
    return index, count, step


def in_grid_order(h: HistogramSet, grid: ScanGrid) -> HistogramSet:
    """The set's rows in the grid's order (one shared offset stays one)."""
    g = h.select(grid.order)
    return g if h.calibration.b_m.size != 1 else replace(g, calibration=h.calibration)


class GridFile:
    """fields.write_fields' view of the file: the flat fields it writes (H (T, N), the grids and
    normals (N, 3)) are stored in the grid's shape; everything else passes through."""

    GRIDS = ("sensor_grid_xyz", "sensor_grid_normals", "laser_grid_xyz", "laser_grid_normals")

    def __init__(self, f, shape):
        self._f, self._shape = f, tuple(shape)

    def create_dataset(self, name, *args, data=None, **kwargs):
        if name == "H":
            data = np.asarray(data).reshape((data.shape[0],) + self._shape)
        elif name in self.GRIDS:
            data = np.asarray(data).reshape(self._shape + (3,))
        return self._f.create_dataset(name, *args, data=data, **kwargs)

    def __setitem__(self, name, value):
        if name in self.GRIDS:
            value = np.asarray(value).reshape(self._shape + (3,))
        self._f[name] = value

    def __getattr__(self, name):
        return getattr(self._f, name)


def mark_grid(f) -> None:
    """The enums of y-tal's grid layout in a file write_fields wrote through GridFile."""
    from .fields import GRID_FORMATS, H_FORMATS
    f["H_format"][0] = H_FORMATS["T_Sx_Sy"]
    for key in ("sensor_grid_format", "laser_grid_format"):
        f[key][0] = GRID_FORMATS["X_Y_3"]


def write_grid_capture(path, h: HistogramSet, grid: ScanGrid, *, device_distance_m=20.0,
                       metadata: dict | None = None, compression: int = 4,
                       force: bool = False) -> Path:
    """write_capture's file (the same fields, scene_info and atomic write) in y-tal's grid
    layout: H (T, Sx, Sy) as T_Sx_Sy, the grids X_Y_3, rows in grid order."""
    import h5py

    from ...core.errors import require
    from ..safe_write import atomic_write
    from .fields import check_writable, is_capture, write_fields

    g = in_grid_order(h, grid)
    check_writable(g, device_distance_m)

    def write(tmp):
        image = io.BytesIO()  # in memory first, as write_capture (a full disk: an OSError)
        with h5py.File(image, "w") as f:
            write_fields(GridFile(f, grid.shape), g, device_distance_m, metadata, compression)
            mark_grid(f)
            shapes = [f[k].shape for k in ("H",) + GridFile.GRIDS]
            require(shapes[0][1:] == grid.shape and all(s == grid.shape + (3,)
                                                        for s in shapes[1:]),
                    "write_grid_capture", f"wrote H and the grids as {shapes}, not in the grid "
                    f"{grid.shape}", "report this: fields.write_fields changed how it writes "
                    "H or the grids")
        with open(tmp, "wb") as fh:
            fh.write(image.getbuffer())
    return atomic_write(path, write, keep_unless=is_capture, force=force, record=False,
                        what="capture", kind="an HDF5 capture (nlos_cl's or y-tal's)")
