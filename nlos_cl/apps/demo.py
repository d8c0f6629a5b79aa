"""`nlos-cl demo`: the paper's scene end to end (simulate, noise, filter, locate), timed, with
both estimators: the paper's argmax and the model fit (the default, `--estimator`)."""
from __future__ import annotations

import json
import time
import warnings

# The frame the demo's positions are in (the paper's scene, which has no capture file): nlos_cl's
# internal frame, which the paper's figures use.
PAPER_FRAME = "the paper's frame (x along the wall, y out from it, z up)"


def _run_once(args, backend, grid):
    """Each stage timed to completion (the device queue drained after it)."""
    import nlos_cl as nl

    from ..physics.scene import paper_scene
    stages = (("scene", lambda _: paper_scene(position=tuple(args.position))),
              ("simulate", lambda scene: (scene, nl.simulate(scene, backend=backend))),
              ("noise", lambda v: v + (nl.add_noise(v[1], args.snr_db, args.seed),)),
              ("gauss_filter", lambda v: v + (nl.gauss_filter(v[2], args.h_ns * 1e-9),)),
              ("locate_paper", lambda v: v + (nl.locate(v[3], grid, estimator="paper",
                                                        return_map=bool(args.png)),)),
              ("locate_model", lambda v: v + (nl.locate(v[3], grid, estimator="model",
                                                        raw=v[2]),)))
    timings, value = {}, None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for label, stage in stages:
            start = time.perf_counter()
            value = stage(value)
            backend.finish()
            timings[label] = time.perf_counter() - start
    return value, timings, sorted({str(w.message) for w in caught})


def _estimates(paper, model, warm) -> dict:
    from ..io.json_format import covariance_json, rounded
    first = model.targets[0]
    return {"paper": {"position": rounded(paper.position), "error_m": round(paper.error_m, 5),
                      "time_s": round(warm["locate_paper"], 4)},
            "model": {"position": rounded(model.position), "error_m": round(model.error_m, 5),
                      "covariance": covariance_json(first.covariance),
                      "extent_m": None if first.extent_m is None else rounded(first.extent_m),
                      "time_s": round(warm["locate_model"], 4)}}


def _print_text(args, result, scene, grid, cold, warm):
    print(f"device   : {result['device']}")
    print(f"scene    : the paper's 0.3 m x 1.6 m rectangle, {result['facets']} facets, "
          f"{result['n_bins']} bins of 1 ps, {args.snr_db} dB noise (seed {args.seed}), "
          f"h = {args.h_ns} ns, {grid.n_cells} grid cells")
    # the demo has no capture file: it speaks the paper's frame, and says so (JSON: "frame")
    print(f"truth    : ({', '.join(f'{v:.3f}' for v in scene.truth)}) m, in {PAPER_FRAME}")
    for name, est in result["estimators"].items():
        mark = "  (default)" if name == args.estimator else ""
        print(f"{name:<9}: ({', '.join(f'{v:.3f}' for v in est['position'])}) m, error "
              f"{est['error_m']:.4f} m, {est['time_s'] * 1e3:.0f} ms{mark}")
    for label, times in (("first run", cold), ("second run", warm)):
        print(f"{label:<11}: " + ", ".join(f"{k} {v * 1e3:.1f} ms" for k, v in times.items())
              + f" (total {sum(times.values()) * 1e3:.0f} ms)")
    print("             (the first run includes building the OpenCL programs)")
    for w in result["warnings"]:
        print(f"note     : {w}")
    if args.png:
        print(f"figure   : {args.png}")


def _check_png(path_text: str, force: bool = False) -> None:
    """Before any work: a figure path that can be written as given (matplotlib would turn a
    folder 'out' into 'out.png' beside it), and not over a file nlos_cl did not write
    (`--png thesis.pdf`) unless --force (nlos_cl.io.safe_write's rule)."""
    from pathlib import Path

    from ..core.errors import require
    from ..io.safe_write import require_writable
    path = Path(path_text)
    require_writable(path, force=force, what="--png", kind="a figure")
    require(path.suffix.lower() in (".png", ".svg", ".pdf"), "--png", f"{path.name} has no "
            ".png, .svg or .pdf suffix", "name the figure e.g. demo.png")


def run(args) -> int:
    from ..core.grid import Grid
    from ..ops.backend import resolve_backend
    if args.track:
        return run_track(args)
    if args.png:
        _check_png(args.png, args.force)
    backend = resolve_backend("reference" if args.reference else args.device)
    grid = Grid.from_ranges(x=(0.0, 6.0), y=(0.01, 6.0), step_m=args.step)
    (scene, sim, noisy, filtered, paper, model), cold, notes = _run_once(args, backend, grid)
    warm = _run_once(args, backend, grid)[1]  # programs built, buffers pooled: steady state
    if args.png:
        from .demo_figure import demo_figure
        from .plotting import write_figure
        answer = model if args.estimator == "model" else paper  # what the text heads with
        write_figure(args.png, lambda fh: demo_figure(noisy.histograms(), filtered.histograms(),
                                                      paper, fh, answer), what="--png",
                     force=args.force)
    estimates = _estimates(paper, model, warm)
    chosen = estimates[args.estimator]
    result = {
        "position": chosen["position"], "truth": [float(v) for v in scene.truth],
        "error_m": chosen["error_m"], "frame": "nlos_cl", "estimator": args.estimator,
        "estimators": estimates, "warnings": notes,
        "device": getattr(backend, "name", str(backend)), "facets": scene.facets().count,
        "n_bins": sim.layout.time_axis.n_bins, "grid_cells": grid.n_cells,
        "snr_db": args.snr_db, "h_s": args.h_ns * 1e-9, "seed": args.seed,
        "timings_s": {k: round(v, 4) for k, v in warm.items()},
        "first_run_timings_s": {k: round(v, 4) for k, v in cold.items()},
        "figure": args.png or None,
    }
    if args.json:
        print(json.dumps(result))
    else:
        _print_text(args, result, scene, grid, cold, warm)
    return 0


def run_track(args) -> int:
    """`nlos-cl demo --track`: the paper's target walking a straight line (30 frames at 10 Hz,
    10 dB), simulated on the device, located per frame and tracked by a Kalman filter."""
    import numpy as np

    from ..core.constants import SPEED_OF_LIGHT
    from ..core.grid import Grid
    from ..core.paths import TimeAxis
    from ..physics.meshes import rectangle
    from ..physics.noise import AWGN
    from ..physics.scene import Target, paper_setup
    from ..physics.trajectory import MovingTarget, Trajectory
    from ..simulation.sequence import simulate_sequence
    from ..tracking import Tracker
    setup, n_frames = paper_setup(), 30
    walk = MovingTarget(Target(rectangle(centre=(3.0, 1.5, 0.0), cell_m=0.02)),
                        Trajectory([0.0, 2.9], [[3.0, 1.5, 0.0], [4.5, 3.0, 0.0]]))
    # 40 .. 53.8 m of path: the walk's last frames (the plate's far corner, 12.5 m of hidden
    # path to detector C after 2d = 40 m) end 4 ns before the record does (4,096 bins cut them)
    axis = TimeAxis(40 / SPEED_OF_LIGHT, 10e-12, 4608)
    frames = simulate_sequence(setup, [walk], n_frames=n_frames, fps=10, time_axis=axis,
                               noise=AWGN(args.snr_db), seed=args.seed)
    grid = Grid.from_ranges(x=(1.5, 6), y=(0.5, 4.5), step_m=0.01)
    tracker = None  # built on the first frame's layout
    raw, tracked, truth, start = [], [], [], time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for frame in frames:
            if tracker is None:
                tracker = Tracker(frame.signals.layout, grid, estimator=args.estimator,
                                  frame_interval_s=0.1)
            tracks = tracker.update(frame.signals, frame.t_s)
            loc = tracker.last_location
            raw.append(loc.position if loc is not None else np.full(3, np.nan))
            live = [t for t in tracks if t.status == "confirmed"]
            tracked.append(live[0].position if live else np.full(3, np.nan))
            truth.append(frame.truths[0])
    wall = time.perf_counter() - start
    notes = sorted({str(w.message) for w in caught})
    raw, tracked, truth = map(np.asarray, (raw, tracked, truth))
    def rms(p):
        return float(np.sqrt(np.nanmean(np.sum((p[5:] - truth[5:]) ** 2, axis=1))))
    result = {"frames": n_frames, "estimator": args.estimator,
              "per_frame_rms_m": round(rms(raw), 4), "tracked_rms_m": round(rms(tracked), 4),
              "frames_per_s": round(n_frames / wall, 1),
              "final_position": [round(float(v), 4) for v in tracked[-1]],
              "final_truth": [round(float(v), 4) for v in truth[-1]], "warnings": notes}
    if args.json:
        print(json.dumps(result))
    else:
        print(f"tracked the paper's target over {n_frames} frames ({args.estimator} estimator, "
              f"{args.snr_db} dB): per-frame RMS {result['per_frame_rms_m']:.3f} m, tracked RMS "
              f"{result['tracked_rms_m']:.3f} m (after frame 5), {result['frames_per_s']} frames/s "
              "including simulation")
        for note in notes:
            print(f"note: {note}")
    return 0
