"""The `nlos-cl` command: info, demo, bench, reproduce, simulate, locate, calibrate."""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np


def _self_check(runtime) -> list[tuple[str, float, float]]:
    """Each kernel against its NumPy twin on a small scene; (name, error, tolerance)."""
    from . import pipeline as pl
    from .histograms import Grid, TimeAxis
    from .reference import NumpyBackend
    from .scene import paper_scene

    scene = paper_scene(facet_size_m=0.05)
    axis = TimeAxis(2 * 20.0 / 299_792_458.0 + 28e-9, 10e-12, 900)  # hidden paths 8.4-11.1 m
    grid = Grid.from_ranges(x=(3.5, 4.5), y=(1.5, 2.5), step_m=0.02)
    results = []
    outs = {}
    for name, be in (("opencl", runtime), ("numpy", NumpyBackend())):
        sim = pl.simulate(scene, axis, backend=be)
        filt = pl.gauss_filter(sim, 0.65e-9)
        outs[name] = (sim.histograms().data, filt.histograms().data,
                      pl.locate(filt, grid, return_map=True).score_map)
    for i, label in enumerate(("forward", "gauss_filter", "ellipse_score")):
        a, b = outs["opencl"][i], outs["numpy"][i]
        results.append((label, float(np.abs(a - b).max() / np.abs(b).max()), 1e-3))
    return results


def cmd_info(args) -> int:
    from . import devices
    entries = devices.list_devices()
    print("OpenCL platforms and devices:")
    if not entries:
        print("  none")
        print(devices.INSTALL_HELP)
        return 1
    for e in entries:
        print("  " + e.label)
    from .runtime import get_runtime
    runtime = get_runtime(args.device)
    print(f"chosen: {runtime.name}")
    failed = False
    for name, err, tol in _self_check(runtime):
        ok = err <= tol
        failed |= not ok
        print(f"  self-check {name:<14} max |kernel - numpy| / max = {err:.2e} "
              f"(tolerance {tol:.0e}) {'ok' if ok else 'FAILED'}")
    if failed:
        print("SELF-CHECK FAILED: the kernels disagree with the NumPy reference on this device",
              file=sys.stderr)
        return 2
    return 0


def cmd_demo(args) -> int:
    from . import pipeline as pl
    from .histograms import Grid
    from .scene import paper_scene

    backend = pl.resolve_backend("reference" if args.reference else args.device)
    grid = Grid.from_ranges(x=(0.0, 6.0), y=(0.01, 6.0), step_m=args.step)

    def run_once():
        """Each stage timed to completion (the device queue drained after it)."""
        timings, value = {}, None
        stages = (("scene", lambda _: paper_scene(position=tuple(args.position))),
                  ("simulate", lambda scene: (scene, pl.simulate(scene, backend=backend))),
                  ("noise", lambda v: v + (pl.add_noise(v[1], args.snr_db, args.seed),)),
                  ("gauss_filter", lambda v: v + (pl.gauss_filter(v[2], args.h_ns * 1e-9),)),
                  ("locate", lambda v: v + (pl.locate(v[3], grid, return_map=bool(args.png)),)))
        for label, stage in stages:
            start = time.perf_counter()
            value = stage(value)
            backend.finish()
            timings[label] = time.perf_counter() - start
        return value, timings

    (scene, sim, noisy, filtered, loc), cold = run_once()
    warm = run_once()[1]  # programs built, buffers pooled: the steady-state cost
    if args.png:
        from .plotting import demo_figure
        demo_figure(noisy.histograms(), filtered.histograms(), loc, args.png)
    result = {
        "position": [round(float(v), 5) for v in loc.position],
        "truth": [float(v) for v in scene.truth],
        "error_m": round(loc.error_m, 5),
        "device": getattr(backend, "name", str(backend)),
        "facets": scene.facets().count,
        "n_bins": sim.layout.time_axis.n_bins,
        "grid_cells": grid.n_cells,
        "snr_db": args.snr_db,
        "h_s": args.h_ns * 1e-9,
        "seed": args.seed,
        "timings_s": {k: round(v, 4) for k, v in warm.items()},
        "first_run_timings_s": {k: round(v, 4) for k, v in cold.items()},
        "figure": args.png or None,
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(f"device   : {result['device']}")
        print(f"scene    : the paper's 0.3 m x 1.6 m rectangle, {result['facets']} facets, "
              f"{result['n_bins']} bins of 1 ps, {args.snr_db} dB noise (seed {args.seed}), "
              f"h = {args.h_ns} ns, {grid.n_cells} grid cells")
        print(f"truth    : ({', '.join(f'{v:.3f}' for v in scene.truth)}) m")
        print(f"located  : ({', '.join(f'{v:.3f}' for v in loc.position)}) m")
        print(f"error    : {loc.error_m:.4f} m")
        for label, times in (("first run", cold), ("second run", warm)):
            print(f"{label:<11}: " + ", ".join(f"{k} {v * 1e3:.1f} ms" for k, v in times.items())
                  + f" (total {sum(times.values()) * 1e3:.0f} ms)")
        print("             (the first run includes building the OpenCL programs)")
        if args.png:
            print(f"figure   : {args.png}")
    return 0


def cmd_bench(args) -> int:
    from pathlib import Path

    from .bench import Bench
    bench = Bench(args.device, smoke=args.smoke)
    bench.run_all()
    print(bench.report(Path(args.out) if args.out else None))
    return 0


def cmd_reproduce(args) -> int:
    from pathlib import Path

    from . import reproduce as rp
    settings = rp.Settings.make(quick=args.quick, seeds=args.seeds)
    start = time.perf_counter()
    results = rp.run(args.name, settings, Path(args.out))
    wall = time.perf_counter() - start
    if args.name == "all" or args.doc:
        doc = Path(args.doc) if args.doc else Path(args.out) / "paper-results.md"
        rp.write_report(results, settings, doc, Path(args.out), wall)
    if args.json:
        print(rp.summary_json(results))
    else:
        for r in results:
            print(f"{r.name}: {r.title} ({r.seconds:.1f} s) -> {args.out}/{r.name}.csv "
                  + " ".join(r.figures))
            print("  " + json.dumps(r.summary)[:600])
        print(f"wall time {wall:.1f} s")
    return 0


def cmd_simulate(args) -> int:
    from . import pipeline as pl
    from .capture import write_capture
    from .histograms import default_time_axis
    from .measured import PhotonCounter
    from .scene import paper_scene

    scene = paper_scene(position=tuple(args.position), facet_size_m=args.facet)
    signals = pl.simulate(scene, default_time_axis(scene.setup, args.dt_ps * 1e-12),
                          backend=pl.resolve_backend(args.device))
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


def cmd_locate(args) -> int:
    from pathlib import Path

    import numpy as np

    from . import pipeline as pl
    from .capture import read_capture
    from .histograms import Grid
    from .measured import fit_calibration, subtract_background, with_calibration

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
    backend = pl.resolve_backend(args.device)
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


def cmd_calibrate(args) -> int:
    import numpy as np

    from .measured import fit_calibration
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


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="nlos-cl", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    p_info = sub.add_parser("info", help="list OpenCL devices, show the chosen one, self-check")
    p_info.add_argument("--device", help="'P:D' indices or part of a device/platform name")
    p_demo = sub.add_parser("demo", help="the paper's scene: simulate, noise, filter, locate")
    p_demo.add_argument("--device", help="'P:D' indices or part of a device/platform name")
    p_demo.add_argument("--reference", action="store_true", help="run on the NumPy twins")
    p_demo.add_argument("--json", action="store_true", help="print one JSON object")
    p_demo.add_argument("--png", default="nlos_demo.png", help="figure path ('' for none)")
    p_demo.add_argument("--snr-db", type=float, default=10.0)
    p_demo.add_argument("--seed", type=int, default=0)
    p_demo.add_argument("--h-ns", type=float, default=0.65, help="Gauss filter window h (ns)")
    p_demo.add_argument("--step", type=float, default=0.01, help="grid step (m)")
    p_demo.add_argument("--position", type=float, nargs=3, default=(4.0, 2.0, 0.0),
                        metavar=("X", "Y", "Z"), help="target centre (m)")
    p_bench = sub.add_parser("bench", help="kernels vs NumPy twins vs the device's limits")
    p_bench.add_argument("--device", help="'P:D' indices or part of a device/platform name")
    p_bench.add_argument("--smoke", action="store_true", help="tiny sizes (for CI)")
    p_bench.add_argument("--out", default="", help="write performance.md/.json/.png here")
    p_rep = sub.add_parser("reproduce", help="re-run an experiment of the paper (or all)")
    p_rep.add_argument("name", choices=["all", "fig5", "fig6", "fig7a", "fig7b", "table1",
                                        "fig8", "fig9", "fig10"])
    p_rep.add_argument("--out", default="out/reproduce", help="folder for figures and CSVs")
    p_rep.add_argument("--seeds", type=int, default=None, help="noise seeds (default 3; 1 quick)")
    p_rep.add_argument("--quick", action="store_true", help="coarse setting (CI)")
    p_rep.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p_rep.add_argument("--doc", default="", help="write the paper-vs-ours report here "
                       "(default with 'all': OUT/paper-results.md)")
    p_sim = sub.add_parser("simulate", help="simulate the paper's scene into a y-tal capture")
    p_sim.add_argument("--out", required=True, help="the .h5 file to write")
    p_sim.add_argument("--position", type=float, nargs=3, default=(4.0, 2.0, 0.0),
                       metavar=("X", "Y", "Z"))
    p_sim.add_argument("--facet", type=float, default=0.01, help="facet size (m)")
    p_sim.add_argument("--dt-ps", type=float, default=10.0, help="bin width (ps)")
    p_sim.add_argument("--snr-db", type=float, default=None, help="add white Gaussian noise")
    p_sim.add_argument("--photons", action="store_true", help="photon-counting detector + TDC")
    p_sim.add_argument("--pulses", type=float, default=80e6, help="laser pulses summed")
    p_sim.add_argument("--tdc-ps", type=float, default=50.0, help="TDC bin (ps)")
    p_sim.add_argument("--seed", type=int, default=0)
    p_sim.add_argument("--device", help="'P:D' indices or part of a device/platform name")
    p_loc = sub.add_parser("locate", help="locate the target of a y-tal capture")
    p_loc.add_argument("file")
    p_loc.add_argument("--grid", type=float, nargs=5, default=(0.0, 6.0, 0.01, 6.0, 0.01),
                       metavar=("X0", "X1", "Y0", "Y1", "STEP"), help="search plane (m)")
    p_loc.add_argument("--z", type=float, nargs=2, default=(0.0, 0.0), metavar=("Z0", "Z1"))
    p_loc.add_argument("--h-ns", type=float, default=0.65, help="Gauss filter window h (ns)")
    p_loc.add_argument("--log", action="store_true", help="sum of logs (many detectors)")
    p_loc.add_argument("--background", help="capture without the target, subtracted first")
    p_loc.add_argument("--negatives", default="clip", choices=["clip", "floor", "keep"])
    p_loc.add_argument("--calibration", help="CSV of (path m, peak time s) pairs: fit Eq. 26")
    p_loc.add_argument("--map", help="save the probability map (.npz)")
    p_loc.add_argument("--json", action="store_true")
    p_loc.add_argument("--device", help="'P:D' indices or part of a device/platform name")
    p_cal = sub.add_parser("calibrate", help="fit path = a t + b (paper Eq. 26) from pairs")
    p_cal.add_argument("pairs", help="CSV rows: known free-space path (m), peak time (s)")
    p_cal.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    from .errors import DeviceError, InputError
    try:
        return {"info": cmd_info, "demo": cmd_demo, "bench": cmd_bench,
                "reproduce": cmd_reproduce, "simulate": cmd_simulate, "locate": cmd_locate,
                "calibrate": cmd_calibrate}[args.command](args)
    except (InputError, DeviceError) as exc:
        print(f"nlos-cl: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
