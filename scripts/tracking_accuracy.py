"""Tracking accuracy and throughput (issue 12's done-when table). Prints markdown tables.

    .venv/bin/python scripts/tracking_accuracy.py [--quick] [--skip NAME ...]

Sections: lines (straight/curved, paper and 8-spot layouts, paper and model estimators),
crossing (two targets, 8 spots, model estimator with targets=2, 10 seeds), box (a static box
with and without background removal), speed (frames/s, 3 x 4,096 bins, 512^2 grid, host frames
to track states), memory (peak RSS tracking a 10,000-frame sequence file).
"""
from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time
import warnings

import numpy as np

import nlos_cl as nl
from nlos_cl.layouts import circle
from nlos_cl.model import ModelEstimator
from nlos_cl.tracking import (BackgroundRemover, ConstantVelocity, MovingTarget, Tracker,
                              Trajectory, read_sequence, simulate_sequence, write_sequence)

FACET, DT = 0.02, 10e-12
GRID = nl.Grid.from_ranges(x=(1.5, 5.5), y=(0.5, 4.5), step_m=0.01)
MOTION = ConstantVelocity(accel_sigma=0.1)


def layouts():
    return {"paper": nl.paper_setup(),
            "8-spot": nl.Setup(detector_spots=circle((-1.0, 0, 0), 0.5, 8))}


def trajectories(n_frames, fps):
    span = n_frames / fps
    arc = np.linspace(0, np.pi / 2, 21)
    curve = np.stack([2.0 + 1.5 * np.sin(arc), 1.5 + 1.5 * (1 - np.cos(arc)), 0 * arc], 1)
    return {"straight": Trajectory([0, span], [[3.0, 1.5, 0], [4.0, 3.0, 0]]),
            "curved": Trajectory(np.linspace(0, span, 21), curve)}


def run(setup, moving, estimator, *, n_frames, fps, seed=0, static=(), background=None,
        max_tracks=1):
    axis = nl.default_time_axis(setup, DT)
    frames = simulate_sequence(setup, moving, n_frames=n_frames, fps=fps, static=static,
                               noise=nl.AWGN(10), seed=seed, facet_size_m=FACET, time_axis=axis)
    tracker, out = None, []
    for fr in frames:
        if tracker is None:
            tracker = Tracker(fr.signals, GRID, estimator=estimator, motion=MOTION,
                              background=background() if background else None,
                              max_tracks=max_tracks, frame_interval_s=1 / fps)
        tracks = tracker.update(fr.signals, fr.t_s)
        out.append((fr, [m.position for m in tracker.last_measurements],
                    {t.id: t.position for t in tracks}))
    return out


def errors(result, first=5):
    raw, trk = [], []
    for fr, meas, tracks in result[first:]:
        truth = fr.truths[0][:2]
        raw.append(min((np.linalg.norm(p[:2] - truth) for p in meas), default=np.nan))
        trk.append(min((np.linalg.norm(p[:2] - truth) for p in tracks.values()), default=np.nan))
    return np.array(raw), np.array(trk)


def rms(e):
    return float(np.sqrt(np.nanmean(np.square(e))))


def lines(quick):
    n, fps = (20, 10) if quick else (50, 10)
    print("\n| trajectory | layout | estimator | per-frame RMS / max (m) | tracked RMS / max (m) "
          "| ratio | pass (<= 0.5, max <= 0.10) |\n|---|---|---|---|---|---|---|")
    for tname, traj in trajectories(n, fps).items():
        for lname, setup in layouts().items():
            target = nl.Target(nl.rectangle(centre=traj.at(0), cell_m=FACET))
            for est in ("paper", "model"):
                raw, trk = errors(run(setup, MovingTarget(target, traj), est, n_frames=n,
                                      fps=fps, seed=1))
                ok = rms(trk) <= 0.5 * rms(raw) and np.nanmax(trk) <= 0.10
                print(f"| {tname} | {lname} | {est} | {rms(raw):.4f} / {np.nanmax(raw):.4f} | "
                      f"{rms(trk):.4f} / {np.nanmax(trk):.4f} | {rms(trk) / rms(raw):.2f} | "
                      f"{'yes' if ok else 'no'} |", flush=True)


def crossing(quick):
    n, fps, seeds = (16, 8, 3) if quick else (20, 10, 10)
    setup = layouts()["8-spot"]
    a = Trajectory([0, n / fps], [[2.5, 2.0, 0], [3.5, 3.0, 0]])
    b = Trajectory([0, n / fps], [[2.5, 3.0, 0], [3.5, 2.0, 0]])
    square = lambda p: nl.Target(nl.rectangle(0.3, 0.3, centre=p, cell_m=FACET))  # noqa: E731
    kept, t0 = 0, time.perf_counter()
    for seed in range(seeds):
        res = run(setup, [MovingTarget(square(a.at(0)), a), MovingTarget(square(b.at(0)), b)],
                  ModelEstimator(targets=2), n_frames=n, fps=fps, seed=seed, max_tracks=2)
        ids = [_nearest(res[3], k) for k in (0, 1)]
        last = [_nearest(res[-1], k) for k in (0, 1)]
        ok = ids[0] != ids[1] and ids == last and None not in ids
        kept += ok
        print(f"  seed {seed}: ids at frame 3 {ids}, at the end {last}: "
              f"{'kept' if ok else 'LOST'}", flush=True)
    print(f"\ncrossing (8 spots, model estimator, targets=2, {n} frames): identities kept in "
          f"{kept} of {seeds} seeds ({(time.perf_counter() - t0) / seeds / n:.2f} s/frame)")


def _nearest(entry, k, radius=0.15):
    fr, _, tracks = entry
    best = min(tracks.items(), key=lambda kv: np.linalg.norm(kv[1][:2] - fr.truths[k][:2]),
               default=(None, None))
    ok = best[0] is not None and np.linalg.norm(best[1][:2] - fr.truths[k][:2]) < radius
    return best[0] if ok else None


def box(quick):
    n, fps = (20, 10) if quick else (50, 10)
    setup = layouts()["paper"]
    traj = trajectories(n, fps)["straight"]
    moving = MovingTarget(nl.Target(nl.rectangle(centre=traj.at(0), cell_m=FACET)), traj)
    clutter = nl.Target(nl.box((0.5, 0.5, 1.0), centre=(2.0, 1.0, 0), cell_m=FACET))
    reference = nl.simulate(nl.Scene(setup, clutter, FACET), nl.default_time_axis(setup, DT))
    print("\n| scene | estimator | per-frame RMS (m) | tracked RMS / max (m) |\n|---|---|---|---|")
    cases = [("no box", (), None), ("box, no removal", (clutter,), None),
             ("box, fixed reference", (clutter,), lambda: BackgroundRemover(reference)),
             ("box, running mean a=0.1", (clutter,), lambda: BackgroundRemover(alpha=0.1))]
    for est in ("paper", "model"):
        for name, static, bg in cases:
            raw, trk = errors(run(setup, moving, est, n_frames=n, fps=fps, seed=1,
                                  static=static, background=bg))
            print(f"| {name} | {est} | {rms(raw):.4f} | {rms(trk):.4f} / {np.nanmax(trk):.4f} |",
                  flush=True)


def stream_frames(n_bins=4096):
    clean = nl.simulate(nl.paper_scene(facet_size_m=0.02),
                        nl.TimeAxis(40 / nl.SPEED_OF_LIGHT, DT, n_bins)).histograms()
    rng = np.random.default_rng(0)
    power = np.sqrt(np.mean(clean.data ** 2, axis=1, keepdims=True) / 10.0)
    return [clean.with_data(clean.data + power * rng.standard_normal(clean.data.shape))
            for _ in range(8)]


def speed(quick):
    frames, n = stream_frames(), 512
    grid = nl.Grid((2.0, 0.5, 0.0), (4 / n, 4 / n, 0.01), (n, n, 1))
    print("\n| estimator | frames | frames/s (host frames -> track states) |\n|---|---|---|")
    for est, count in (("paper", 60 if quick else 300), ("model", 5 if quick else 20)):
        tracker = Tracker(frames[0], grid, estimator=est, motion=MOTION)
        tracker.update(frames[0], 0.0)  # builds the kernels
        t0 = time.perf_counter()
        for k in range(1, count + 1):
            tracker.update(frames[k % 8], k / 10)
        print(f"| {est} | {count} | {count / (time.perf_counter() - t0):.1f} |", flush=True)


def memory(quick):
    n = 1000 if quick else 10_000
    frames = stream_frames()
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "long.h5")
        t0 = time.perf_counter()
        write_sequence(path, ((k / 100, frames[k % 8]) for k in range(n)))
        size = os.path.getsize(path)
        print(f"\nmemory: wrote {n} frames ({size / 2**20:.0f} MiB) in "
              f"{time.perf_counter() - t0:.1f} s", flush=True)
        seq = read_sequence(path)
        tracker = Tracker(seq, nl.Grid((2.0, 0.5, 0.0), (1 / 32, 1 / 32, 0.01), (128, 128, 1)),
                          motion=MOTION)
        marks, t0 = {}, time.perf_counter()
        for frame in seq:
            tracker.update(frame.histograms, frame.t_s)
            if frame.index + 1 in (n // 10, n // 2, n):
                marks[frame.index + 1] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        rate = n / (time.perf_counter() - t0)
    print("peak RSS (MiB) after " + ", ".join(f"{k} frames: {v / 1024:.0f}"
                                              for k, v in marks.items())
          + f" ({rate:.0f} frames/s on a 128^2 grid; the file is {size / 2**20:.0f} MiB)")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--only", nargs="*", default=None,
                   choices=["lines", "crossing", "box", "speed", "memory"])
    args = p.parse_args(argv)
    warnings.simplefilter("ignore")  # collinear spots: the model estimator's height warning
    print(f"device: {nl.resolve_backend().name}; {os.cpu_count()} CPU cores")
    for name in args.only or ["speed", "memory", "lines", "box", "crossing"]:
        t0 = time.perf_counter()
        globals()[name](args.quick)
        print(f"({name}: {time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
