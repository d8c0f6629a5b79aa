"""The sections of `reproduce tracking`, one function each: (cfg, Common) -> (CSV rows, the
section's markdown). tracking.yaml says what each runs; runs tracks and measures."""
from __future__ import annotations

import os
import resource
import tempfile
import time

import numpy as np

import nlos_cl as nl
from nlos_cl.localization.model import ModelEstimator
from nlos_cl.tracking import (BackgroundRemover, ConstantVelocity, Interacting, MovingTarget,
                              SensorNoise, Tracker, Trajectory, kalman, read_sequence,
                              simulate_sequence, write_sequence)
from nlos_cl.tracking.options import TrackRules

from . import cases as tc
from . import report
from . import runs


def _path_rows(cfg, c, case, path_name, setup, moving, estimator, sec, **options) -> dict:
    """Track one sequence of `sec`'s frames and seed; its table row."""
    res, tracker, lagged = runs.run(c, setup, moving, estimator, n_frames=sec["frames"],
                                    seed=sec["seed"], **options)
    return runs.path_row(c, case, *runs.errors(c, res, tracker, lagged),
                         bound=runs.bound_ratio(c, res, tc.bound_path(cfg, path_name)))


def lines(cfg, c):
    """The walker on every path x layout x estimator, 10 dB AWGN."""
    sec, rows = cfg["lines"], []
    for pname in sec["paths"]:
        traj = tc.trajectory(cfg, pname)
        for lname in sec["layouts"]:
            moving = MovingTarget(c.walker(cfg, traj.at(0)), traj)
            for est in sec["estimators"]:
                rows.append(_path_rows(cfg, c, f"{pname}, {lname}, {est}", pname,
                                       tc.setup(cfg, lname), moving, est, sec))
    return rows, report.path_table("trajectory, layout, estimator", c.lag, rows)


def synthetic(cfg, c):
    """The constant-velocity filter alone (Tracker.step, no estimator) on the bound's paths
    measured with white errors of sigma_m, seeds x process noises (and the IMM of a steady and
    a manoeuvring one: imm_accel_sigmas): what the motion model allows. Ratio: filter RMS /
    per-frame RMS from frame c.first on, pooled over the seeds."""
    sec, rows = cfg["synthetic"], []
    sigma, t = sec["sigma_m"], np.arange(sec["frames"]) / c.fps
    layout = nl.simulate(nl.paper_scene(facet_size_m=0.05)).layout  # (only its geometry)
    motions = {a: ConstantVelocity(accel_sigma=a) for a in sec["accel_sigmas"]}
    steady, turning = sec["imm_accel_sigmas"]  # and the IMM of two of them
    motions[f"IMM {steady:g} / {turning:g}"] = Interacting(accel_sigmas=(steady, turning))
    for accel, motion in motions.items():
        for pname in sec["paths"]:
            family, params = tc.bound_path(cfg, pname)
            truth, filtered, measured = family(params, t), [], []
            for seed in range(sec["seeds"]):
                rng = np.random.default_rng(seed)
                tracker = Tracker(layout, c.grid, frame_interval_s=1 / c.fps, motion=motion)
                for k, tk in enumerate(t):
                    z = truth[k] + sigma * rng.standard_normal(2)
                    m = kalman.Measurement(np.arange(2), z, sigma ** 2 * np.eye(2), np.r_[z, 0])
                    (track,) = tracker.step([m], tk)
                    if k >= c.first:
                        filtered.append(np.sum((track.position[:2] - truth[k]) ** 2))
                        measured.append(np.sum((z - truth[k]) ** 2))
            rows.append({"accel_sigma": accel, "path": pname,
                         "filter_rms_m": float(np.sqrt(np.mean(filtered))),
                         "per_frame_rms_m": float(np.sqrt(np.mean(measured))),
                         "ratio": float(np.sqrt(np.mean(filtered) / np.mean(measured)))})
    return rows, report.synthetic_table(rows)


def box(cfg, c):
    """The walker past a static box: the sensor's noise floor fixed at the target-only first
    frame's snr_db, then each removal (none, a target-free reference, a running mean)."""
    sec = cfg["box"]
    setup, traj = tc.setup(cfg, sec["layout"]), tc.trajectory(cfg, sec["path"])
    moving = MovingTarget(c.walker(cfg, traj.at(0)), traj)
    spec = sec["clutter"]
    clutter = nl.Target(nl.box(tuple(spec["size_m"]), centre=tuple(spec["centre"]),
                               cell_m=c.facet_m))
    axis = nl.default_time_axis(setup, c.dt_s)
    first = next(simulate_sequence(setup, moving, n_frames=1, fps=c.fps, facet_size_m=c.facet_m,
                                   time_axis=axis))
    noise = SensorNoise.from_snr(first.signals, c.snr_db)
    n_ref, alpha = sec["reference_frames"], sec["running_mean_alpha"]
    reference = (_reference(c, setup, clutter, axis, noise, n_ref, sec["reference_seed"])
                 if "reference" in sec["cases"] else None)
    cases = {"no box": ("no box", (), None),
             "no removal": ("box, no removal", (clutter,), None),
             "reference": (f"box, reference (mean of {n_ref} target-free frames)", (clutter,),
                           lambda: BackgroundRemover(reference, clip=False)),
             "running mean": (f"box, running mean a={alpha:g}", (clutter,),
                              lambda: BackgroundRemover(alpha=alpha, clip=False))}
    rows = []
    for est in sec["estimators"]:
        for key in sec["cases"]:
            name, static, background = cases[key]
            rows.append(_path_rows(cfg, c, f"{name}, {est}", sec["path"], setup, moving, est,
                                   sec, static=static, background=background, noise=noise))
    return rows, report.path_table("scene, estimator", c.lag, rows)


def _reference(c, setup, clutter, axis, noise, frames, seed0):
    """A target-free capture as a sensor records it: the mean of `frames` noisy frames of the
    clutter alone. Its noise, 1/sqrt(frames) of a frame's, is the same in every frame it is
    subtracted from, so no filter averages it away: kept small."""
    sig = nl.simulate(nl.Scene(setup, clutter, c.facet_m), axis)
    mean = sum(noise.apply(sig, seed0 + k).histograms().data for k in range(frames)) / frames
    return sig.histograms().with_data(mean)


def crossing(cfg, c):
    """Two squares crossing, the model estimator with targets=2: per seed, whether the track ids
    nearest the targets at check_frame are different and the same at the last frame."""
    sec, rows = cfg["crossing"], []
    n, (w, h) = sec["frames"], sec["size_m"]
    setup = tc.setup(cfg, sec["layout"])
    paths = [Trajectory([0, n / c.fps], segment) for segment in sec["paths"]]
    for seed in range(sec["seeds"]):
        start = time.perf_counter()
        pair = [MovingTarget(nl.Target(nl.rectangle(w, h, centre=p.at(0), cell_m=c.facet_m)), p)
                for p in paths]
        res, _, _ = runs.run(c, setup, pair, ModelEstimator(targets=2), n_frames=n, seed=seed,
                             max_tracks=2)
        ids = [_nearest(res[sec["check_frame"]], k, sec["radius_m"]) for k in (0, 1)]
        last = [_nearest(res[-1], k, sec["radius_m"]) for k in (0, 1)]
        rows.append({"seed": seed, "ids_start": ids, "ids_end": last,
                     "kept": ids[0] != ids[1] and ids == last and None not in ids,
                     "seconds": time.perf_counter() - start})
    return rows, report.crossing_list(rows, len(setup.detector_spots), n, sec["check_frame"])


def _nearest(entry, k, radius):
    """The id of the track nearest target k, if within `radius`; else None."""
    fr, _, tracks, _ = entry
    best = min(tracks.items(), key=lambda kv: np.linalg.norm(kv[1][:2] - fr.truths[k][:2]),
               default=(None, None))
    ok = best[0] is not None and np.linalg.norm(best[1][:2] - fr.truths[k][:2]) < radius
    return best[0] if ok else None


def _stream_frames(c, n_bins):
    """8 noisy frames of the paper's scene (snr_db measured per detector), used in turn."""
    clean = nl.simulate(nl.paper_scene(facet_size_m=c.facet_m),
                        nl.TimeAxis(40 / nl.SPEED_OF_LIGHT, c.dt_s, n_bins)).histograms()
    rng = np.random.default_rng(0)
    power = np.sqrt(np.mean(clean.data ** 2, axis=1, keepdims=True) / 10 ** (c.snr_db / 10))
    return [clean.with_data(clean.data + power * rng.standard_normal(clean.data.shape))
            for _ in range(8)]


def _square_grid(n):
    """n x n cells over 4 x 4 m of the hidden area (from (2, 0.5)), on z = 0."""
    return nl.Grid((2.0, 0.5, 0.0), (4 / n, 4 / n, 0.01), (n, n, 1))


def speed(cfg, c):
    """Frames per second, host frames to track states, after a first frame builds the kernels."""
    sec, rows = cfg["speed"], []
    frames, grid = _stream_frames(c, sec["bins"]), _square_grid(sec["grid_cells"])
    for est in tc.ESTIMATORS:
        count = sec["frames"][est]
        tracker = Tracker(frames[0], grid, estimator=est, motion=c.motion)
        tracker.update(frames[0], 0.0)  # builds the kernels
        t0 = time.perf_counter()
        for k in range(1, count + 1):
            tracker.update(frames[k % 8], k / c.fps)
        rows.append({"estimator": est, "frames": count,
                     "frames_per_s": count / (time.perf_counter() - t0)})
    return rows, report.speed_table(rows)


def memory(cfg, c):
    """Peak RSS while tracking a long file: first with max_history = frames / 10 (bounded
    history and smoothing record), then the default None (both kept whole). ru_maxrss is the
    process's peak, so the bounded run goes first."""
    sec, rows = cfg["memory"], []
    n, frames = sec["frames"], _stream_frames(c, sec["bins"])
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "long.h5")
        t0 = time.perf_counter()
        write_sequence(path, ((k / 100, frames[k % 8]) for k in range(n)))
        written = {"file_frames": n, "file_mib": os.path.getsize(path) / 2 ** 20,
                   "write_s": time.perf_counter() - t0}
        for history in (n // 10, None):
            seq = read_sequence(path)
            tracker = Tracker(seq, _square_grid(sec["grid_cells"]), estimator="paper",
                              motion=c.motion, rules=TrackRules(max_history=history))
            marks, t0 = {}, time.perf_counter()
            for frame in seq:
                tracker.update(frame.histograms, frame.t_s)
                if frame.index + 1 in (n // 10, n // 2, n):
                    marks[frame.index + 1] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
            rate = n / (time.perf_counter() - t0)
            rows += [{"max_history": str(history), "after_frames": k, "peak_rss_mib": v / 1024,
                      "frames_per_s": rate, "grid_cells": sec["grid_cells"], **written}
                     for k, v in marks.items()]
    return rows, report.memory_list(rows)
