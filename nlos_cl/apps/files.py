"""`nlos-cl simulate | locate | calibrate`: y-tal capture files in and out, and the paper's
Eq. 26 calibration from measured (path, peak time) pairs.

`locate` is nl.locate_capture (nlos_cl/localization/capture.py) with the command's options,
in the capture's own frame: --region is given along the file's axes, and positions,
covariances, truth and the region are reported in them (the JSON's `frame` says which).
Without --region the search region is derived from the capture (nlos_cl.localization.region:
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


def write_figure(path, draw, *, what: str, force: bool = False, keep_unless=None):
    """The figure `draw(fh)` saves (a plotting function given an open binary file) written to
    `path` through nlos_cl.io.safe_write.atomic_write: whole or not at all, never over a file
    nlos_cl did not write unless force, never through a link or onto a device. matplotlib takes
    a file object's format from savefig.format, so that is set from the suffix (.png, .pdf)."""
    from pathlib import Path

    import matplotlib

    from ..io.safe_write import atomic_write
    fmt = Path(path).suffix.lstrip(".").lower() or "png"

    def write(tmp):
        with matplotlib.rc_context({"savefig.format": fmt}), open(tmp, "wb") as fh:
            draw(fh)
    return atomic_write(path, write, keep_unless=keep_unless, force=force, what=what,
                        kind="a figure")


def is_map(path) -> bool:
    """A map `locate --map` wrote: an .npz whose arrays are exactly score, x, y, z (read with
    allow_pickle=False: nothing in the file runs)."""
    import numpy as np
    try:
        with np.load(path, allow_pickle=False) as data:
            return sorted(data.files) == ["score", "x", "y", "z"]
    except Exception:  # noqa: BLE001 - anything unreadable is not our map
        return False


def _save_map(args, i, n_sets, loc, grid):
    from pathlib import Path

    import numpy as np

    from ..io.safe_write import atomic_write
    out = Path(args.map) if n_sets == 1 else Path(args.map).with_suffix(f".{i}.npz")
    x, y, z = grid.axes()

    def write(tmp):
        with open(tmp, "wb") as fh:  # a file object: savez would append .npz to a name
            np.savez_compressed(fh, score=loc.score_map, x=x, y=y, z=z)
    atomic_write(out, write, keep_unless=is_map, force=args.force, what="--map",
                 kind="a map nlos-cl locate wrote")
    return str(out)


def _check_map_path(args) -> None:
    """Before any work: --map must be writable (never over a file nlos_cl did not write: an
    .npz of the user's own is kept unless --force)."""
    from ..io.safe_write import require_writable
    require_writable(args.map, keep_unless=is_map, force=args.force, what="--map",
                     kind="a map nlos-cl locate wrote")
    if args.region is not None and args.step is not None:  # the map's size is known now
        import math

        from ..core.limits import require_memory
        cells = math.prod(math.floor(abs(hi - lo) / args.step) + 1
                          for lo, hi in zip(args.region[::2], args.region[1::2]))
        # scored on the device (4 B a cell), read back as float64 (8 B) and compressed
        require_memory("--region", 12.0 * cells, f"--map of {cells:.3g} cells", "a smaller "
                       "--region or a larger --step (or leave --map out: the search alone "
                       "need not score every cell)")


NO_TARGET_STATUS = 3  # `nlos-cl locate`: no laser point held target signal


def _estimator(args):
    """--estimator, or with --reflectance the model fit that knows it (estimators'
    choose_estimator; without one, locate_capture applies the same policy per laser point)."""
    if args.reflectance is None:
        return args.estimator
    from ..localization.estimators import choose_estimator
    from .cli_types import OPTION_FLAGS
    return choose_estimator(args.estimator, targets=args.targets, reflectance=args.reflectance,
                            names=OPTION_FLAGS)[0]


def locate(args) -> int:
    """nl.locate_capture with the command's options; the JSON is its as_json()."""
    from ..localization.capture import locate_capture
    if args.map:
        _check_map_path(args)
    region = None if args.region is None else list(zip(args.region[::2], args.region[1::2]))
    h_s = None if args.h_ns is None else args.h_ns * 1e-9
    found = locate_capture(args.file, region=region, step_m=args.step, h_s=h_s, pulses=args.pulses,
                           estimator=_estimator(args), targets=args.targets,
                           log_mode=True if args.log else None, background=args.background,
                           negatives=args.negatives, calibration=args.calibration,
                           return_map=bool(args.map), backend=args.device,
                           names=("--region", "--step"))
    entries = []
    for point in found.points:
        entry = point.as_json()
        if args.map:
            entry["map"] = _save_map(args, point.laser_point, len(found.points),
                                     point.location, point.grid)
        entries.append(entry)
        for w in point.warnings:
            print(f"nlos-cl: warning: laser point {point.laser_point}: {w}", file=sys.stderr)
    if args.json:
        print(json.dumps(found.as_json(entries)))
    else:
        frame = found.frame
        for r in entries:
            print(f"laser point {r['laser_point']}: " + (
                  f"located {r['position']} m in the file's frame ({frame.name})"
                  if r["detected"] else f"no target (argmax of noise {r['argmax_cell']} m)")
                  + (f", truth {r['truth']}, error {r['error_m']:.4f} m" if r["truth"] else ""))
    # exit status 3: no laser point's histograms hold target signal (docs/captures.md)
    return 0 if any(r["detected"] for r in entries) else NO_TARGET_STATUS


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
