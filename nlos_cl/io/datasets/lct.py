"""Confocal scans as LCT publishes them (O'Toole, Lindell, Wetzstein, "Confocal
non-line-of-sight imaging based on the light-cone transform", Nature 555:338, 2018): a .mat
file with rect_data (Nx, Ny, T) photon counts and width, the half side of the scanned square.

Facts, from the upstream `cnlos_reconstruction.m` (as summarised in
../shared/realdata/lct/README.md): 4 ps bins; the data are "pre-rectified": t = 0 is the wall
bounce, so a hidden point at distance r from a scan point lands at path 2 r (ours: hidden path
= c t); the scan grid is Nx x Ny points spaced evenly over [-width, width] on both wall axes.

Not documented upstream: which wall axis each array axis is, and its direction. Our choice:
rect_data[i, j] is the wall point (x, z) = (u_i, u_j), u = linspace(-width, width), x along
the first array axis, z (up) along the second. `transpose` swaps the two, `flip` ("x", "z" or
"xz") reverses those axes; a hidden point's depth y does not depend on either choice.
The upstream script zeroes the first 600 bins (the direct return) before reconstructing;
`gate_bins` does the same here, and is 0 (no gating) unless asked for.
"""
from __future__ import annotations

import numpy as np

from ...core.constants import SPEED_OF_LIGHT
from ...core.errors import require
from ...core.histograms import HistogramSet
from ...core.paths import PathCalibration, TimeAxis
from .matfile import load, variables

BIN_PS = 4.0  # cnlos_reconstruction.m: bin_resolution = 4e-12


def read_lct(path, *, dt_ps: float = BIN_PS, t0_ps: float = 0.0, width_m: float | None = None,
             transpose: bool = False, flip: str = "", gate_bins: int = 0) -> HistogramSet:
    """An LCT .mat file as a confocal (paired, laser = detector point) HistogramSet. width_m:
    the scan's half side (default: the file's `width`)."""
    require(np.isfinite(dt_ps) and dt_ps > 0, "dt_ps", f"must be positive, got {dt_ps}",
            f"pass e.g. {BIN_PS}")
    require(np.isfinite(t0_ps), "t0_ps", f"must be finite, got {t0_ps}", "pass e.g. 0")
    require(flip in ("", "x", "z", "xz", "zx"), "flip", f"must be x, z or xz, got {flip!r}",
            "pass --flip x, z or xz")
    held = variables(path)
    require("rect_data" in held or "meas" not in held, f"{path}: rect_data", "is missing; the "
            "file holds `meas`, f-k migration's layout", "pass --format fk (or no --format)")
    cube = load(path, "rect_data", 3)
    require(int(gate_bins) == gate_bins and 0 <= gate_bins < cube.shape[2], "gate_bins",
            f"must be a bin count in 0..{cube.shape[2] - 1}, got {gate_bins}", "pass e.g. 600")
    if width_m is None:
        width_m = float(load(path, "width", 2).ravel()[0])
    require(np.isfinite(width_m) and width_m > 0, "width_m", f"must be a positive half side "
            f"in metres, got {width_m}", "pass e.g. 0.35")
    if transpose:
        cube = cube.transpose(1, 0, 2)
    nx, nz, n_t = cube.shape
    u, v = np.linspace(-width_m, width_m, nx), np.linspace(-width_m, width_m, nz)
    u, v = (u[::-1] if "x" in flip else u), (v[::-1] if "z" in flip else v)
    x, z = np.meshgrid(u, v, indexing="ij")  # row k = (i, j) = divmod(k, nz), as reshape does
    spots = np.column_stack([x.ravel(), np.zeros(x.size), z.ravel()])
    data = cube.reshape(nx * nz, n_t)
    data[:, :int(gate_bins)] = 0.0  # our own float64 copy: the file is not touched
    axis = TimeAxis(t0_ps * 1e-12, dt_ps * 1e-12, n_t)
    return HistogramSet(data, axis, spots, spots, PathCalibration(SPEED_OF_LIGHT, [0.0]))
