"""The pipeline: simulate -> noise -> Gauss filter -> locate, on any backend.

Every stage takes and returns `Signals`: histograms resident on a backend (an OpenCL device
buffer, or a NumPy array for the reference backend) in units of `scale_w` watts, with the
metadata the next stage needs (time axis, wall spots, calibration). Stages chain on the device;
only the tiny argmax partials and the 3 x 3 neighbourhood of the peak come back to the host.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from .constants import LOG_FLOOR, PAPER_H_S, PRODUCT_FLOOR, SPEED_OF_LIGHT
from .errors import InputError, require
from .fit import GaussFit, fit_gaussians
from .histograms import Grid, HistogramSet, PathCalibration, TimeAxis, default_time_axis
from .reference import NumpyBackend, gauss_taps
from .scene import Scene



def resolve_backend(backend=None):
    """None: the shared OpenCL runtime on the default device; 'reference' or 'numpy': the
    float64 NumPy twins; a device spec string ('0:0', 'pocl', ...) or a Runtime/NumpyBackend."""
    if backend is None or isinstance(backend, str):
        if isinstance(backend, str) and backend.lower() in ("reference", "numpy"):
            return NumpyBackend()
        from .runtime import get_runtime
        return get_runtime(backend)
    return backend


@dataclass(frozen=True)
class Signals:
    """Histograms on a backend: physical value (W) = scale_w * values in `handle`."""

    backend: object
    handle: object
    scale_w: float
    layout: HistogramSet  # metadata; its data are not used (see `histograms()`)

    @property
    def n_detectors(self) -> int:
        return self.layout.n_detectors

    def histograms(self) -> HistogramSet:
        """Read back to the host, in watts."""
        return self.layout.with_data(self.backend.to_numpy(self.handle) * self.scale_w)

    def _derive(self, handle, scale_w=None) -> "Signals":
        return Signals(self.backend, handle, self.scale_w if scale_w is None else scale_w,
                       self.layout)


def upload(histograms: HistogramSet, backend=None) -> Signals:
    """Put host histograms on a backend, normalised so that float32 neither under- nor
    overflows (measured powers are ~1e-20 W)."""
    require(isinstance(histograms, HistogramSet), "histograms",
            f"expected a nlos_cl.HistogramSet, got {type(histograms).__name__}",
            "wrap your array: HistogramSet(data, time_axis, detector_spots, laser_spot, calibration)")
    backend = resolve_backend(backend)
    peak = float(np.max(np.abs(histograms.data)))
    scale = peak if peak > 0 else 1.0
    return Signals(backend, backend.from_numpy(histograms.data / scale), scale, histograms)


def _as_signals(value, backend) -> Signals:
    if isinstance(value, Signals):
        return value
    return upload(value, backend)


# ---------------------------------------------------------------------------- simulate

def simulate(scene: Scene, time_axis: TimeAxis | None = None, *, backend=None) -> Signals:
    """Paper Eq. 19-21: each facet's Gaussian pulse, delayed by (2 d + r1 + r2) / c and
    attenuated by the BRDFs, four cosines and 1 / (r1^2 r2^2), integrated over every time bin.
    The result is the mean power per bin in watts (as `scale_w` * device values)."""
    require(isinstance(scene, Scene), "scene", f"expected a nlos_cl.Scene, got "
            f"{type(scene).__name__}", "build one with nlos_cl.paper_scene() or Scene(setup, target)")
    setup = scene.setup
    axis = time_axis if time_axis is not None else default_time_axis(setup)
    require(isinstance(axis, TimeAxis), "time_axis", f"expected a nlos_cl.TimeAxis, got "
            f"{type(axis).__name__}", "pass TimeAxis(t0_s, dt_s, n_bins)")
    backend = resolve_backend(backend)
    calibration = PathCalibration.for_setup(setup)
    pulse = setup.pulse
    n_det = setup.n_detectors
    # Bin edges in hidden-path metres, through the exact (simulation) calibration.
    edge0 = calibration.offsets(n_det) + SPEED_OF_LIGHT * axis.t0_s
    dpath = np.full(n_det, SPEED_OF_LIGHT * axis.dt_s)
    sigma_path = SPEED_OF_LIGHT * pulse.sigma_s
    facets = scene.facets()
    hist, span = backend.simulate(facets, setup.detector_spots, setup.laser_spot, edge0, dpath,
                                  sigma_path, axis.n_bins)
    if not np.all(np.isfinite(span)):
        raise InputError("scene.target: no facet faces both the laser spot and a detector spot, "
                         "so nothing returns to the wall. Fix: turn the target towards the wall "
                         "(one-sided rectangles light only on their normal's side)")
    _check_window(axis, edge0, dpath, span, sigma_path)
    scale = 0.5 * pulse.energy_j * setup.power_scale(scene.target.brdf) / axis.dt_s
    layout = HistogramSet(np.zeros((n_det, axis.n_bins)), axis, setup.detector_spots,
                          setup.laser_spot, calibration, truth=scene.truth)
    return Signals(backend, hist, scale, layout)


def _check_window(axis, edge0, dpath, span, sigma_path):
    start, stop = edge0, edge0 + dpath * axis.n_bins
    first, last = span[:, 0] - 3 * sigma_path, span[:, 1] + 3 * sigma_path
    for d in range(len(span)):
        t_first = axis.t0_s + (first[d] - start[d]) / SPEED_OF_LIGHT
        t_last = axis.t0_s + (last[d] - start[d]) / SPEED_OF_LIGHT
        if stop[d] <= first[d] or start[d] >= last[d]:
            raise InputError(
                f"time_axis: the window [{axis.t0_s * 1e9:.3f}, {axis.t_end_s * 1e9:.3f}] ns "
                f"misses detector {d}'s signal, which arrives in [{t_first * 1e9:.3f}, "
                f"{t_last * 1e9:.3f}] ns. Fix: set t0_s <= {t_first:.4e} and n_bins >= "
                f"{math.ceil((t_last - min(t_first, axis.t0_s)) / axis.dt_s)}")
        if start[d] > first[d] or stop[d] < last[d]:
            warnings.warn(f"time_axis cuts detector {d}'s signal short: it arrives in "
                          f"[{t_first * 1e9:.3f}, {t_last * 1e9:.3f}] ns", stacklevel=3)


# ---------------------------------------------------------------------------- clean

def add_noise(signals, snr_db: float = 10.0, seed: int = 0, *, backend=None) -> Signals:
    """Additive white Gaussian noise, snr_db below each histogram's measured power (mean of
    squares over the whole record, as MATLAB's awgn(x, snr, 'measured')), seeded."""
    sig = _as_signals(signals, backend)
    require(isinstance(snr_db, (int, float)) and math.isfinite(snr_db), "snr_db",
            f"must be a finite number of decibels, got {snr_db!r}", "pass e.g. 10")
    require(isinstance(seed, (int, np.integer)) and seed >= 0, "seed",
            f"must be a non-negative integer, got {seed!r}", "pass e.g. 0")
    normal = sig.backend.standard_normal(sig.layout.data.shape, int(seed))
    return sig._derive(sig.backend.add_awgn(sig.handle, normal, float(snr_db)))


def gauss_filter(signals, h_s: float = PAPER_H_S, *, backend=None) -> Signals:
    """Paper Eq. 24: a Gaussian of sigma = h / 3 over the window [t - h, t + h]."""
    sig = _as_signals(signals, backend)
    axis = sig.layout.time_axis
    require(isinstance(h_s, (int, float)) and math.isfinite(h_s) and h_s > 0, "h_s",
            f"the filter window must be a positive time in seconds, got {h_s!r}",
            "pass e.g. 0.65e-9 (the paper's h)")
    require(h_s >= axis.dt_s, "h_s", f"window {h_s:.3e} s is narrower than one bin "
            f"({axis.dt_s:.3e} s), so the filter would only rescale the data",
            "use h_s of at least one bin width, typically 0.65e-9")
    require(h_s < axis.n_bins * axis.dt_s, "h_s",
            f"window {h_s:.3e} s is longer than the whole record "
            f"({axis.n_bins * axis.dt_s:.3e} s)", "use a smaller h_s or a longer time axis")
    taps = gauss_taps(h_s, axis.dt_s)
    return sig._derive(sig.backend.gauss_filter(sig.handle, taps))


def gauss_fit(signals, *, backend=None) -> tuple[Signals, GaussFit]:
    """Paper Eq. 25 baseline: a converged least-squares Gaussian per whole histogram (SciPy,
    on the host). Returns the fitted curves on the same backend, and the fit parameters."""
    sig = _as_signals(signals, backend)
    values = sig.backend.to_numpy(sig.handle)
    fit = fit_gaussians(values, sig.layout.time_axis.centres())
    return sig._derive(sig.backend.from_numpy(fit.curves(sig.layout.time_axis.centres()))), fit


# ---------------------------------------------------------------------------- locate

@dataclass(frozen=True)
class Location:
    """Where the joint likelihood peaks: `position` refined below the cell size."""

    position: np.ndarray  # (3,) metres
    cell_position: np.ndarray  # centre of the best cell
    score: float  # joint likelihood (or its log) at the best cell
    grid: Grid
    truth: np.ndarray | None = None
    score_map: np.ndarray | None = field(default=None, repr=False)  # (nz, ny, nx) if asked

    @property
    def error_m(self) -> float | None:
        if self.truth is None:
            return None
        return float(np.linalg.norm(self.position - self.truth))


def locate(signals, grid: Grid | None = None, *, log_mode: bool = False,
           return_map: bool = False, backend=None) -> Location:
    """Score every grid cell by the signals at its ellipse path |c - O| + |c - spot| per
    detector, combine (product, or sum of logs when log_mode), take the argmax and refine it
    with a parabola per axis through the log-score of the best cell and its neighbours."""
    sig = _as_signals(signals, backend)
    grid = Grid() if grid is None else grid
    require(isinstance(grid, Grid), "grid", f"expected a nlos_cl.Grid, got {type(grid).__name__}",
            "build one with Grid.from_ranges(x=(0, 6), y=(0.01, 6), step_m=0.01)")
    be, lay = sig.backend, sig.layout
    path0, dpath = lay.score_axis()
    stats = be.row_stats(sig.handle)
    score = be.ellipse_score(sig.handle, stats, lay.detector_spots, lay.laser_spot, path0,
                             1.0 / dpath, grid, log_mode, LOG_FLOOR)
    flat, best = be.argmax(score)
    nx, ny, nz = grid.shape
    # Below these the joint likelihood is numerically zero: every detector at its log floor,
    # or a product beyond float32's range (the float64 twin would otherwise "locate" on 1e-67).
    floor = lay.n_detectors * math.log(LOG_FLOOR) if log_mode else PRODUCT_FLOOR
    if flat < 0 or not best > floor:
        raise InputError("grid: no cell has a non-zero likelihood from every detector: the "
                         "signals do not reach the grid. Fix: check that the grid covers the "
                         "hidden area the time axis sees, and the calibration; with many "
                         "detectors use log_mode=True")
    iz, rem = divmod(flat, nx * ny)
    iy, ix = divmod(rem, nx)
    patch = _neighbourhood(be, score, grid.shape, ix, iy, iz)
    cell = np.array([o + s * i for o, s, i in zip(grid.origin, grid.step, (ix, iy, iz))])
    offset = _parabolic_offsets(patch if log_mode else np.log(np.maximum(patch, 1e-300)))
    position = cell + offset * np.asarray(grid.step)
    full = be.to_numpy(score) if return_map else None
    return Location(position, cell, best, grid, lay.truth, full)


def _neighbourhood(be, score, shape, ix, iy, iz):
    """3 x 3 x 3 scores around the best cell (NaN outside the grid), read row by row."""
    nx, ny, nz = shape
    patch = np.full((3, 3, 3), np.nan)
    y0, y1 = max(iy - 1, 0), min(iy + 2, ny)
    x0, x1 = max(ix - 1, 0), min(ix + 2, nx)
    for dz in (-1, 0, 1):
        z = iz + dz
        if 0 <= z < nz:
            rows = be.read_rows(score, z, y0, y1)[:, x0:x1]
            patch[dz + 1, y0 - iy + 1:y1 - iy + 1, x0 - ix + 1:x1 - ix + 1] = rows
    return patch


def _parabolic_offsets(logp):
    """Per axis (x, y, z), the vertex of the parabola through (-1, 0, +1) cells, in cells."""
    offsets = np.zeros(3)
    lines = (logp[1, 1, :], logp[1, :, 1], logp[:, 1, 1])
    for axis, (m, c, p) in enumerate(lines):
        curvature = m - 2 * c + p
        if np.isfinite(m) and np.isfinite(p) and curvature < 0:
            offsets[axis] = float(np.clip(0.5 * (m - p) / curvature, -0.5, 0.5))
    return offsets
