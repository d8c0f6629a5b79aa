"""`nlos-cl simulate | locate | calibrate`: y-tal capture files in and out, and the paper's
Eq. 26 calibration from measured (path, peak time) pairs."""
from __future__ import annotations

import json


def simulate(args) -> int:
    from .. import pipeline as pl
    from ..backend import resolve_backend
    from ..capture import write_capture
    from ..histograms import default_time_axis
    from ..measured import PhotonCounter
    from ..scene import paper_scene

    scene = paper_scene(position=tuple(args.position), facet_size_m=args.facet)
    signals = pl.simulate(scene, default_time_axis(scene.setup, args.dt_ps * 1e-12),
                          backend=resolve_backend(args.device))
    if args.snr_db is not None:
        signals = pl.add_noise(signals, args.snr_db, args.seed)
    hist = signals.histograms()
    noise = f"AWGN {args.snr_db} dB" if args.snr_db is not None else "none"
    if args.photons:
        counter = PhotonCounter(n_pulses=args.pulses, tdc_bin_s=args.tdc_ps * 1e-12)
        hist = counter.counts(hist, args.seed)
        noise = f"photon counting ({counter})"
    path = write_capture(args.out, hist, device_distance_m=scene.setup.device_distance_m,
                         metadata={"scene": "paper rectangle 0.3 m x 1.6 m",
                                   "noise": noise, "seed": args.seed})
    print(f"wrote {path}: {hist.n_detectors} detectors x {hist.time_axis.n_bins} bins of "
          f"{hist.time_axis.dt_s * 1e12:g} ps, target at {[float(v) for v in scene.truth]}, noise: {noise}")
    return 0


def locate(args) -> int:
    from pathlib import Path

    import numpy as np

    from .. import pipeline as pl
    from ..backend import resolve_backend
    from ..capture import read_capture
    from ..histograms import Grid
    from ..measured import fit_calibration, subtract_background, with_calibration

    sets = read_capture(args.file)
    if args.background:
        backgrounds = read_capture(args.background)
        sets = [subtract_background(h, b, negatives=args.negatives)
                for h, b in zip(sets, backgrounds)]
    calibration = None
    if args.calibration:
        pairs = np.loadtxt(args.calibration, delimiter=",", ndmin=2)
        fit = fit_calibration(pairs[:, 0], pairs[:, 1])
        calibration = fit.calibration
        sets = [with_calibration(h, calibration) for h in sets]
    x0, x1, y0, y1, step = args.grid
    grid = Grid.from_ranges(x=(x0, x1), y=(y0, y1), z=tuple(args.z), step_m=step)
    backend = resolve_backend(args.device)
    results = []
    for i, hist in enumerate(sets):
        filtered = pl.gauss_filter(hist, args.h_ns * 1e-9, backend=backend)
        loc = pl.locate(filtered, grid, log_mode=args.log, return_map=bool(args.map))
        entry = {"laser_point": i, "laser_spot": [float(v) for v in hist.laser_spot],
                 "position": [round(float(v), 5) for v in loc.position],
                 "truth": None if loc.truth is None else [float(v) for v in loc.truth],
                 "error_m": None if loc.error_m is None else round(loc.error_m, 5)}
        if args.map:
            out = Path(args.map) if len(sets) == 1 else Path(args.map).with_suffix(f".{i}.npz")
            x, y, z = grid.axes()
            np.savez_compressed(out, score=loc.score_map, x=x, y=y, z=z)
            entry["map"] = str(out)
        results.append(entry)
    summary = {"file": str(args.file), "device": getattr(backend, "name", str(backend)),
               "grid_cells": grid.n_cells, "h_s": args.h_ns * 1e-9,
               "calibration": None if calibration is None else
               {"a_m_per_s": calibration.a_m_per_s, "b_m": float(calibration.b_m[0])},
               **(results[0] if len(results) == 1 else {"per_laser_point": results})}
    if args.json:
        print(json.dumps(summary))
    else:
        for r in results:
            print(f"laser point {r['laser_point']}: located {r['position']} m"
                  + (f", truth {r['truth']}, error {r['error_m']:.4f} m" if r["truth"] else ""))
    return 0


def calibrate(args) -> int:
    import numpy as np

    from ..measured import fit_calibration
    pairs = np.loadtxt(args.pairs, delimiter=",", ndmin=2)
    fit = fit_calibration(pairs[:, 0], pairs[:, 1])
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


