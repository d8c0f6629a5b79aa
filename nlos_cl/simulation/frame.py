"""Simulate one frame: the forward operation for a scene (paper Eq. 19-21), and noise on top.

`simulate` runs the forward operation for a scene on any backend; `add_noise` applies a noise
model (nlos_cl.physics.noise) once. A stream of frames: nlos_cl.simulation.sequence."""
from __future__ import annotations

import math

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.errors import InputError, require, warn
from ..core.histograms import Layout
from ..core.paths import PathAxis, PathCalibration, TimeAxis, default_time_axis
from ..ops.backend import resolve_backend
from ..ops.signals import Signals, as_signals
from ..physics.noise import AWGN, NoiseModel


def simulate(scene, time_axis: TimeAxis | None = None, *, backend=None) -> Signals:
    """Paper Eq. 19-21: each facet's Gaussian pulse, delayed by (2 d + r1 + r2) / c and
    attenuated by the BRDFs, four cosines and 1 / (r1^2 r2^2), integrated over every time bin.
    Facets that do not see the laser spot and a detector spot (scene.visibility) send nothing
    to it; with setup.finite_spots the signal is the mean over quadrature points of both disks.
    The result is the mean power per bin in watts (as `scale_w` * device values)."""
    from ..physics.scene import Scene  # trimesh: only when simulating
    require(isinstance(scene, Scene), "scene", f"expected a nlos_cl.Scene, got "
            f"{type(scene).__name__}", "build one with nlos_cl.paper_scene() or Scene(setup, target)")
    setup = scene.setup
    axis = time_axis if time_axis is not None else default_time_axis(setup)
    require(isinstance(axis, TimeAxis), "time_axis", f"expected a nlos_cl.TimeAxis, got "
            f"{type(axis).__name__}", "pass TimeAxis(t0_s, dt_s, n_bins)")
    from ..core.limits import require_memory
    require_memory("time_axis", 12.0 * setup.n_detectors * axis.n_bins,  # float32 + float64
                   f"{setup.n_detectors} x {axis.n_bins} bins of {axis.dt_s:.3g} s",
                   "use wider bins (dt_s) or a shorter window (n_bins)")
    window_s = axis.n_bins * axis.dt_s  # a longer pulse: every bin sees a flat part of it
    require(setup.pulse.fwhm_s <= window_s, "setup.pulse.fwhm_s", f"a {setup.pulse.fwhm_s:.3g} "
            f"s pulse is longer than the whole {window_s:.3g} s time axis, so no echo in it "
            "can be timed", "use a pulse shorter than the window (the paper's is 70e-12 s) or "
            "a longer time axis (n_bins)")
    backend = resolve_backend(backend)
    layout = Layout(axis, setup.detector_spots, setup.laser_spot,
                    PathCalibration.for_setup(setup), scene.truth, scene.truths)
    paths = layout.path_axis()  # bin edges in hidden-path metres, through the exact calibration
    sigma_path = SPEED_OF_LIGHT * setup.pulse.sigma_s
    watts = 0.5 * setup.pulse.energy_j / axis.dt_s  # W per unit of kernel value and power scale
    total, scale = None, 1.0  # (scale: the first target's, set with total)
    for i, target in enumerate(scene.targets):  # third-order light: the targets' signals add
        hist, span = _target_signal(backend, scene, i, paths, sigma_path, axis.n_bins)
        field = "scene.target" if i == 0 else f"scene.more_targets[{i - 1}]"
        dark = ~np.all(np.isfinite(span), axis=1)
        if dark.any() and scene.visibility(i) is None:
            raise InputError(f"{field}: no facet faces both the laser spot and a detector spot, "
                             "so nothing returns to the wall. Fix: turn the target towards the "
                             "wall (one-sided rectangles light only on their normal's side)")
        if dark.any():  # shadowed by the scene for these detectors: nothing to check there
            warn(f"{field} is hidden from detector(s) {np.flatnonzero(dark).tolist()} by the "
                 "scene (occlusion): it sends them nothing")
            mid = 0.5 * (paths.start_m + paths.stop_m)
            span = np.where(dark[:, None], mid[:, None], span)
        _check_window(axis, paths, span, sigma_path)
        own = watts * setup.power_scale(target.reflectance.scale)
        if total is None:
            total, scale = hist, own
        else:  # in the first target's units (a device-side axpy on OpenCL)
            total = total + hist * (own / scale)
    return Signals(backend, total, scale, layout)


def _target_signal(backend, scene, i, paths, sigma_path, n_bins):
    """Target i's histograms: one forward call per pair of spot quadrature points (one call
    for point spots), weighted and summed; the span is the union of the calls' spans."""
    setup, target = scene.setup, scene.targets[i]
    lasers, laser_w, offsets, spot_w = setup.spot_samples()
    args = (paths.start_m, paths.step_m, sigma_path, n_bins, target.reflectance)
    visible = scene.visibility(i)
    total, spans = None, []
    for laser, wl in zip(lasers, laser_w):
        for offset, wd in zip(offsets, spot_w):
            hist, span = backend.call("forward", scene.facets(i), setup.detector_spots + offset,
                                      laser, *args, "deposit", visible)
            spans.append(span)
            w = float(wl * wd)
            if total is None:
                total = hist if w == 1.0 else hist * w
            else:
                total = total + hist * w
    spans = np.stack(spans)
    return total, np.stack([spans[..., 0].min(axis=0), spans[..., 1].max(axis=0)], axis=1)


def _check_window(axis: TimeAxis, paths: PathAxis, span, sigma_path):
    start, stop = paths.start_m, paths.stop_m
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
            warn(f"time_axis cuts detector {d}'s signal short: it arrives in "
                 f"[{t_first * 1e9:.3f}, {t_last * 1e9:.3f}] ns")


def add_noise(signals, snr_db: float = 10.0, seed: int = 0, *, model: NoiseModel | None = None,
              backend=None) -> Signals:
    """Noise from `model` (anything with apply(signals, seed): nlos_cl.AWGN, PhotonCounter);
    by default the paper's white Gaussian noise at `snr_db` below each histogram's power."""
    sig = as_signals(signals, backend)
    return (model if model is not None else AWGN(snr_db)).apply(sig, seed)
