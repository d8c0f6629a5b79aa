"""Which laser point goes with which sensor point in a y-tal capture, and so which rows of H
make which HistogramSet.

y-tal's own rules (diegoroyo/tal, tal/io/capture_data.py, `NLOSCaptureData`):
- `is_laser_paired_to_sensor()`: False for H_format T_Lx_Ly_Sx_Sy and T_Li_Si (every laser
  point with every sensor point: "exhaustive"); for T_Sx_Sy and T_Si, True when the laser and
  sensor grids have the same format and the same shape but the last axis (one laser point per
  sensor point, "paired").
- `is_confocal()`: False for T_Lx_Ly_Sx_Sy and T_Li_Si; for T_Sx_Sy and T_Si,
  `np.allclose(sensor_grid_xyz, laser_grid_xyz)`: paired with each laser point on its sensor
  point.
Here: one laser point for all sensors -> one set with laser_spot (3,); paired or confocal ->
one set with laser_spot (N, 3); exhaustive -> one set per laser point (laser_spot (3,)), or with
joint=True one paired set of all L x S pairs, laser-major (row i * S + j: laser i, sensor j).

y-tal's enums as stored (tal/enums.py) define H_format 0-4 only; the Fourier-domain formats
(10-13, complex H) and the polarized layout (a trailing Stokes axis of 4) are taken from
a user's report of such files, not from y-tal's source: we refuse the first and read Stokes
channel 0 (S0, the total intensity, which is what the ellipse and forward models describe)
with a warning.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...core.errors import require, warn

FOURIER_H_FORMATS = range(10, 14)  # y-tal's Fourier-domain H (complex), refused


STOKES = 4  # a trailing axis of 4 Stokes parameters (S0..S3): polarized captures


@dataclass(frozen=True)
class Block:
    """One HistogramSet to read: H[index] (time first) gives its rows; sensors[k] and
    lasers[k] index the flattened grids for row k; paired: one laser spot per row."""

    index: tuple
    sensors: np.ndarray
    lasers: np.ndarray
    paired: bool


def check_h_format(code, H, path) -> None:
    """Refuse the Fourier-domain formats and complex H in one line that names the fix."""
    where = f"capture {path}: H_format"
    arr = np.ravel(np.asarray(code))
    fourier = arr.size == 1 and np.issubdtype(arr.dtype, np.integer) and int(arr[0]) in \
        FOURIER_H_FORMATS
    require(not fourier and not np.issubdtype(H.dtype, np.complexfloating),
            where if fourier else f"capture {path}: H",
            f"{'is ' + str(int(arr[0])) if fourier else f'has dtype {H.dtype}'}: a "
            "Fourier-domain capture (complex H over frequencies), but nlos_cl locates from "
            "time histograms", "transform H back to time (inverse FFT along its frequency "
            "axis) and store it as float32 with H_format T_Si, T_Sx_Sy, T_Li_Si or T_Lx_Ly_Sx_Sy")


def stokes_channel(shape, expect, path) -> tuple:
    """() for H of the expected shape; (0,) (channel S0, with a warning) for a trailing Stokes
    axis of 4."""
    if tuple(shape) == tuple(expect) + (STOKES,):
        warn(f"capture {path}: H has a trailing Stokes axis of {STOKES} (a polarized capture): "
             "reading its first channel S0 (total intensity) only")
        return (0,)
    return ()


def plan(h_format, shape, sensors, lasers, formats, path, joint=False) -> list[Block]:
    """The HistogramSets of a capture as Blocks, after checking H's shape against the grids.
    `formats`: (sensor_grid_format, laser_grid_format) as stored, or None where absent."""
    where = f"capture {path}: H"
    n_t = shape[0] if len(shape) else 0
    s_shape, l_shape = sensors.shape[:-1], lasers.shape[:-1]
    n_s, n_l = int(np.prod(s_shape)), int(np.prod(l_shape))
    if h_format in ("T_Si", "T_Sx_Sy"):
        expect = (n_t,) + s_shape
    elif h_format == "T_Lx_Ly_Sx_Sy":
        expect = (n_t,) + l_shape + s_shape
    else:  # T_Li_Si: (T, L, S), as y-tal 0.20's code reads value 4
        expect = (n_t, n_l, n_s)
    stokes = stokes_channel(shape, expect, path)
    require(tuple(shape[:len(expect)]) == expect and len(shape) == len(expect) + len(stokes),
            where, f"has shape {tuple(shape)}, but {h_format} with sensor_grid_xyz "
            f"{sensors.shape} and laser_grid_xyz {lasers.shape} needs {expect}",
            "store H with the time axis first, then the laser grid's and the sensor grid's "
            "shapes (as y-tal's H_format says)")
    require(n_t >= 2, where, f"has {n_t} time bins", "store at least 2 time bins")
    rows, whole = np.arange(n_s), (slice(None),) * len(expect) + stokes if stokes else ()
    if h_format in ("T_Si", "T_Sx_Sy"):
        same = l_shape == s_shape and (None in formats or formats[0] == formats[1])
        # y-tal pairs one laser point with one sensor point too; here only where it is the
        # sensor point (a single confocal spot: Keyhole's scans), so that one laser point and
        # one detector elsewhere stays the one-laser layout it always was
        paired = same and (n_l > 1 or bool(np.allclose(lasers, sensors)))
        require(n_l == 1 or paired, f"capture {path}: laser_grid_xyz",
                f"has {n_l} points (shape {lasers.shape}) for H_format {h_format} with "
                f"sensor_grid_xyz {sensors.shape}: neither one laser point nor one per sensor "
                "point (y-tal's is_laser_paired_to_sensor)", "store one laser point, one per "
                "sensor point in the sensor grid's shape and format, or use H_format T_Li_Si")
        return [Block(whole, rows, rows if paired else np.zeros(n_s, int), paired)]
    h_lasers = (n_l,) if h_format == "T_Li_Si" else l_shape  # H's laser axes
    tail = (slice(None),) * (len(expect) - 1 - len(h_lasers)) + stokes if stokes else ()
    if joint:
        return [Block(whole, np.tile(rows, n_l), np.repeat(np.arange(n_l), n_s), True)]
    return [Block((slice(None),) + tuple(int(v) for v in np.unravel_index(i, h_lasers)) + tail,
                  rows, np.full(n_s, i), False) for i in range(n_l)]


def read_block(H, block: Block) -> np.ndarray:
    """(rows, n_t) float64 from H[block.index] (time first)."""
    data = np.asarray(H[block.index] if block.index else H[()], dtype=np.float64)
    return data.reshape(data.shape[0], -1).T
