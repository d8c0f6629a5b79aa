"""`nlos-cl simulate | locate | calibrate`: y-tal capture files in and out, and the paper's
Eq. 26 calibration from measured (path, peak time) pairs.

`locate` works in the capture's own frame: --region is given along the file's axes, and
positions, covariances, truth and the region are reported in them (the JSON's `frame` says
which). Without --region the search region is derived from the capture (nlos_cl.io.ytal.frames:
in front of the wall, around every spot, out to what the time window reaches); a coarse
default region is refined around the answer, and an answer on the region's edge warns.
"""
from __future__ import annotations

import json
import sys


def _paper_spec(args):
    """The paper's scene from the command-line options, as a scene file would give it."""
    from ..physics.noise import PhotonCounter
    from ..physics.noise import AWGN
    from ..core.paths import default_time_axis
    from ..physics.scene import paper_scene
    from ..io.scenefile import SceneSpec
    scene = paper_scene(position=tuple(args.position or (4.0, 2.0, 0.0)),
                        facet_size_m=args.facet or 0.01)
    noise = None
    if args.photons:
        noise = PhotonCounter(n_pulses=args.pulses, tdc_bin_s=args.tdc_ps * 1e-12)
    elif args.snr_db is not None:
        noise = AWGN(args.snr_db)
    axis = default_time_axis(scene.setup, (args.dt_ps or 10.0) * 1e-12)
    return SceneSpec(scene, axis, noise, args.seed or 0, "paper rectangle 0.3 m x 1.6 m")


def _scene_spec(args):
    from ..core.errors import require
    if args.scene is None:
        return _paper_spec(args)
    clash = [f for f in ("position", "facet", "dt_ps", "snr_db", "seed") if getattr(args, f)
             is not None] + (["photons"] if args.photons else [])
    require(not clash, f"--{clash[0].replace('_', '-')}" if clash else "", "describes the "
            "paper's scene, but a scene file was given", "put it in the scene file instead")
    from ..io.scenefile import load_scene
    return load_scene(args.scene)


def _simulate_frames(args, spec) -> int:
    """A sequence file: frame k at t = k / fps, moving targets on their trajectories, static
    ones (clutter) simulated once, per-frame noise seeded from the scene's seed."""
    from ..ops.backend import resolve_backend
    from ..tracking import MovingTarget, simulate_sequence, write_sequence
    scene = spec.scene
    moving = [MovingTarget(t, p) for t, p in zip(scene.targets, spec.trajectories) if p]
    static = [t for t, p in zip(scene.targets, spec.trajectories) if p is None]
    frames = simulate_sequence(scene.setup, moving, static=static, n_frames=args.frames,
                               fps=args.fps, time_axis=spec.time_axis, noise=spec.noise,
                               seed=spec.seed, facet_size_m=scene.facet_size_m,
                               backend=resolve_backend(args.device))
    path = write_sequence(args.out, frames, fps=args.fps,
                          device_distance_m=scene.setup.device_distance_m,
                          metadata={"scene": spec.description or str(args.scene),
                                    "noise": repr(spec.noise), "seed": spec.seed},
                          force=args.force)
    print(f"wrote {path}: {args.frames} frames at {args.fps:g} Hz, {len(moving)} moving and "
          f"{len(static)} static target(s)")
    return 0


def simulate(args) -> int:
    import nlos_cl as nl
    from ..ops.backend import resolve_backend
    from ..io.ytal.capture import write_capture
    from ..core.errors import require
    spec = _scene_spec(args)
    require(args.frames is None or args.scene is not None, "--frames", "needs a scene file "
            "with moving targets", "give a scene file whose targets have a `trajectory:`")
    if args.frames is not None:
        require(spec.moving, "--frames", "asks for a sequence, but no target of the scene "
                "file has a trajectory", "give a target `trajectory: {t_s: [...], positions: "
                "[...]}` in place of `position`")
        return _simulate_frames(args, spec)
    scene = spec.scene
    signals = nl.simulate(scene, spec.time_axis, backend=resolve_backend(args.device))
    if spec.noise is not None:
        signals = nl.add_noise(signals, model=spec.noise, seed=spec.seed)
    hist = signals.histograms()
    noise = repr(spec.noise) if spec.noise is not None else "none"
    truths = [[float(v) for v in t] for t in scene.truths]
    path = write_capture(args.out, hist, device_distance_m=scene.setup.device_distance_m,
                         metadata={"scene": spec.description or str(args.scene),
                                   "targets": truths, "noise": noise, "seed": spec.seed},
                         force=args.force)
    print(f"wrote {path}: {hist.n_detectors} detectors x {hist.time_axis.n_bins} bins of "
          f"{hist.time_axis.dt_s * 1e12:g} ps, {len(truths)} target(s) at {truths} "
          f"(nlos_cl's frame), noise: {noise}")
    return 0


def _read(args):
    """The capture's sets (background subtracted, calibration applied) and its frame."""
    from ..io.ytal.capture import read_capture, read_capture_with_frame
    sets, frame = read_capture_with_frame(args.file)
    if args.background:
        from ..localization.background import subtract_background
        backgrounds = read_capture(args.background)
        sets = [subtract_background(h, b, negatives=args.negatives)
                for h, b in zip(sets, backgrounds)]
    calibration = None
    if args.calibration:  # (measured: imported only where a file asks for it)
        from ..io.calibration import fit_calibration, read_calibration_pairs, with_calibration
        calibration = fit_calibration(*read_calibration_pairs(args.calibration)).calibration
        sets = [with_calibration(h, calibration) for h in sets]
    return sets, frame, calibration


def _region(args, hist, frame):
    """(grid, was it derived) in our frame: --region along the file's axes, else the default."""
    from ..localization.region import default_region, region_step
    h_s = args.h_ns * 1e-9
    if args.region is None:
        return default_region(hist, h_s), True
    a0, a1, b0, b1, c0, c1 = args.region
    step = args.step if args.step is not None else region_step(hist, h_s)
    grid = frame.grid(((a0, a1), (b0, b1), (c0, c1)), step)
    from ..core.limits import memory_limit
    need = 4 * grid.n_cells
    if need > memory_limit():
        from ..core.errors import InputError
        raise InputError(f"--region: {grid.n_cells:.3g} cells at a {step:g} m step need "
                         f"{need / 2**30:.1f} GiB for the score map, more than the "
                         f"{memory_limit() / 2**30:.1f} GiB allowed (half the memory available)."
                         " Fix: a smaller region or a larger --step")
    return grid, False


def _estimator(args):
    if args.estimator == "paper":
        return "paper"
    from ..localization.model import ModelEstimator
    return ModelEstimator(targets=args.targets)


def _locate_one(args, hist, frame, backend):
    """The paper's argmax on the region (refined on a fine zoom where the derived region had to
    be coarsened), then the chosen estimator on the final grid; warnings collected."""
    import warnings as pywarnings

    import nlos_cl as nl
    from ..localization.region import on_region_edge, region_step, zoom_region
    from ..ops.signals import upload
    region, derived = _region(args, hist, frame)
    log_mode = args.log or hist.n_detectors > 8  # products of many detectors underflow float32
    h_s = args.h_ns * 1e-9
    raw = upload(hist, backend)  # once: filtered here, and fitted by the model estimator
    filtered = nl.gauss_filter(raw, h_s)
    grid = region
    if derived and min(region.step) > region_step(hist, h_s) * 1.001:
        coarse = nl.locate(filtered, region, log_mode=log_mode, estimator="paper")
        grid = zoom_region(coarse.position, region, hist, h_s)
    with pywarnings.catch_warnings(record=True) as caught:
        pywarnings.simplefilter("always")
        loc = nl.locate(filtered, grid, log_mode=log_mode, estimator=_estimator(args),
                        raw=raw, return_map=bool(args.map))
    notes = [str(w.message) for w in caught]
    if on_region_edge(loc.position, region):
        notes.append(f"the answer lies on the search region's edge "
                     f"({_ranges(frame, frame.ranges(region))}), so the target may be outside "
                     "it. Fix: widen it with --region (ranges along the file's axes) or record "
                     "a longer time window")
    return loc, grid, log_mode, notes


def _ranges(frame, lo_hi) -> str:
    return ", ".join(f"{a} {lo:.3g}..{hi:.3g} m" for a, (lo, hi) in zip(frame.axes, lo_hi))


def _entry(i, hist, loc, grid, log_mode, frame, warnings) -> dict:
    import numpy as np
    m = np.asarray(frame.matrix)  # internal = m @ file, so a covariance maps as m^T C m
    r5 = lambda v: [round(float(x), 5) for x in np.ravel(v)]  # noqa: E731
    targets = [{"position": r5(frame.from_internal(t.position)),
                "covariance": _covariance_json(t.covariance, m),
                "extent_m": None if t.extent_m is None else r5(t.extent_m)}
               for t in loc.targets]
    truth = None if loc.truth is None else r5(frame.from_internal(loc.truth))
    return {"laser_point": i, "laser_spot": r5(frame.from_internal(hist.laser_spot)),
            "position": targets[0]["position"], "targets": targets, "truth": truth,
            "argmax_cell": r5(frame.from_internal(loc.cell_position)),
            "error_m": None if loc.error_m is None else round(loc.error_m, 5),
            "estimator": loc.estimator, "log_mode": log_mode,
            "region": {"ranges_m": [list(r) for r in frame.ranges(grid)],
                       "step_m": min(grid.step), "cells": grid.n_cells},
            "warnings": warnings}


def _covariance_json(cov, m):
    """A 3 x 3 covariance in the file's frame (m^2). The frame is a signed permutation, so the
    entries are moved, not mixed: an unobservable axis (infinite variance) becomes null in its
    row and column only (JSON has no infinity)."""
    import numpy as np
    if cov is None:
        return None
    c = np.asarray(cov, dtype=np.float64)
    axis = np.abs(m).argmax(axis=0)  # file axis i is internal axis axis[i]
    sign = m[axis, np.arange(3)]
    out = c[np.ix_(axis, axis)] * np.outer(sign, sign)
    return [[float(f"{v:.6g}") if np.isfinite(v) else None for v in row] for row in out]


def _save_map(args, i, n_sets, loc, grid):
    from pathlib import Path

    import numpy as np

    from ..io.safe_write import atomic_write
    out = Path(args.map) if n_sets == 1 else Path(args.map).with_suffix(f".{i}.npz")
    x, y, z = grid.axes()

    def write(tmp):
        with open(tmp, "wb") as fh:  # a file object: savez would append .npz to a name
            np.savez_compressed(fh, score=loc.score_map, x=x, y=y, z=z)
    atomic_write(out, write, keep_unless=lambda p: p.suffix == ".npz", force=args.force,
                 what="--map", kind="a .npz map")
    return str(out)


def _check_map_path(args) -> None:
    """Before any work: --map must be writable as a .npz map (never over another kind of file)."""
    from ..io.safe_write import require_writable
    require_writable(args.map, keep_unless=lambda p: p.suffix == ".npz", force=args.force,
                     what="--map", kind="a .npz map")


def locate(args) -> int:
    from ..ops.backend import resolve_backend
    if args.map:
        _check_map_path(args)
    sets, frame, calibration = _read(args)
    backend = resolve_backend(args.device)
    results = []
    for i, hist in enumerate(sets):
        loc, grid, log_mode, warnings = _locate_one(args, hist, frame, backend)
        entry = _entry(i, hist, loc, grid, log_mode, frame, warnings)
        if args.map:
            entry["map"] = _save_map(args, i, len(sets), loc, grid)
        results.append(entry)
        for w in warnings:
            print(f"nlos-cl: warning: laser point {i}: {w}", file=sys.stderr)
    summary = {"file": str(args.file), "frame": frame.as_json(),
               "device": getattr(backend, "name", str(backend)), "h_s": args.h_ns * 1e-9,
               "calibration": None if calibration is None else
               {"a_m_per_s": calibration.a_m_per_s, "b_m": float(calibration.b_m[0])},
               **(results[0] if len(results) == 1 else {"per_laser_point": results})}
    if args.json:
        print(json.dumps(summary))
    else:
        for r in results:
            print(f"laser point {r['laser_point']}: located {r['position']} m in the file's "
                  f"frame ({frame.name})" + (f", truth {r['truth']}, error {r['error_m']:.4f} m"
                                             if r["truth"] else ""))
    return 0


def calibrate(args) -> int:
    from ..io.calibration import fit_calibration, read_calibration_pairs
    fit = fit_calibration(*read_calibration_pairs(args.pairs))
    result = {"a_m_per_s": fit.calibration.a_m_per_s, "b_m": float(fit.calibration.b_m[0]),
              "rmse_m": fit.rmse_m, "r2": fit.r2, "pairs": fit.n_pairs,
              "speed_error": fit.speed_error}
    if args.json:
        print(json.dumps(result))
    else:
        print(f"path = {fit.calibration.a_m_per_s * 1e-7:.4f} cm/ns * t + "
              f"{fit.calibration.b_m[0] * 100:.2f} cm  (RMSE {fit.rmse_m * 100:.2f} cm, "
              f"R^2 {fit.r2:.4f}, slope {100 * fit.speed_error:+.2f} % from c, {fit.n_pairs} pairs)")
    return 0
