"""Random confocal walks tracked as `nlos-cl track` tracks them, one estimator against another.

Each draw (seed s: numpy's default_rng(1000 + s)): a confocal grid of n x n wall spots (n 3-4,
pitch 0.1-0.4 m, centred at x in [-0.5, 0.5] m; each spot's detection point 1 mm from its laser
point, as the forward model needs), a plate facing the wall (0.3-0.6 m wide, 0.4-1.2 m tall)
walking a straight line at 0.3-1.0 m/s from x in [-1.5, 1.5], y in [1.0, 2.5], z in
[-0.2, 0.2] m, 30 frames at 10 frames/s of 250 ps bins (a consumer sensor's), each histogram
simulated by the forward model with its own laser spot, AWGN at 0-20 dB. The frames are
written as a sequence file and tracked through nl.track_sequence with `estimator=E`
(every other default: region, sigma, motion), the error being the longest-lived confirmed
track's distance to the plate's centre.

    .venv/bin/python scripts/confocal_track_draws.py [--draws 24] [--estimators paper mean]

Stop 47 (docs/tracking.md): 24 draws, paper -> mean: per-draw median error 0.134 -> 0.108 m
(median over draws), 90th percentile 0.232 -> 0.219, worst 0.236 -> 0.263; the mean nearer on
19 of 24. ~12 s a draw on 2 cores (4 min 40 s for the 24).
"""
from __future__ import annotations

import argparse
import math
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

import nlos_cl as nl
from nlos_cl.tracking import read_sequence, write_sequence

FRAMES, FPS = 30, 10.0
AXIS = nl.default_time_axis(nl.paper_setup(), 250e-12, max_hidden_path_m=10.0)


def draw(seed: int) -> dict:
    g = np.random.default_rng(1000 + seed)
    n, pitch, cx = int(g.integers(3, 5)), g.uniform(0.1, 0.4), g.uniform(-0.5, 0.5)
    spots = [(cx + (i - (n - 1) / 2) * pitch, 0.0, (j - (n - 1) / 2) * pitch)
             for i in range(n) for j in range(n)]
    width, height = g.uniform(0.3, 0.6), g.uniform(0.4, 1.2)
    start = np.array([g.uniform(-1.5, 1.5), g.uniform(1.0, 2.5), g.uniform(-0.2, 0.2)])
    angle, speed = g.uniform(0, 2 * np.pi), g.uniform(0.3, 1.0)
    velocity = speed * np.array([math.cos(angle), math.sin(angle), 0.0])
    return dict(seed=seed, n=n, pitch=pitch, spots=spots, width=width, height=height,
                start=start, velocity=velocity, snr_db=g.uniform(0.0, 20.0))


def frames_of(d: dict) -> list:
    """(t_s, HistogramSet, [truth]) per frame: each spot's histogram its own simulation."""
    spots = np.asarray(d["spots"], float)
    out = []
    for k in range(FRAMES):
        centre = d["start"] + d["velocity"] * k / FPS
        centre[1] = max(centre[1], 0.6)  # a walker turning back stays in front of the wall
        mesh = nl.rectangle(d["width"], d["height"], centre=tuple(centre), normal=(0.0, -1.0, 0.0),
                            cell_m=0.03)
        rows, offsets, scale = [], [], None
        for s in d["spots"]:
            setup = nl.paper_setup(laser_spot=s, detector_spots=[(s[0] + 1e-3, s[1], s[2])])
            h = nl.simulate(nl.Scene(setup, nl.Target(mesh), 0.03, truth=tuple(centre)),
                            AXIS).histograms()
            rows.append(h.data[0])
            offsets.append(h.calibration.offsets(1)[0])
            scale = h.calibration.a_m_per_s
        cal = nl.PathCalibration(scale, np.array(offsets))
        frame = nl.HistogramSet(np.array(rows), AXIS, spots, spots, cal, truth=tuple(centre))
        frame = nl.add_noise(frame, d["snr_db"], seed=d["seed"] * 100 + k).histograms()
        out.append((k / FPS, frame, [tuple(centre)]))
    return out


def track(path: Path, estimator: str, truth: np.ndarray) -> dict:
    seq = read_sequence(path)
    tracker = nl.track_sequence(seq, estimator=estimator).tracker
    ours, ids = np.full((len(seq), 3), np.nan), set()
    for k, frame in enumerate(seq.frames()):
        confirmed = [t for t in tracker.update(frame.histograms, frame.t_s)
                     if t.status == "confirmed"]
        ids |= {t.id for t in confirmed}
        if confirmed:  # our frame, as the truth
            ours[k] = max(confirmed, key=lambda t: len(t.history)).position
    seen = np.isfinite(ours[:, 0])
    error = np.linalg.norm(ours[seen] - truth[seen], axis=1)
    return {"median": float(np.median(error)) if len(error) else math.nan,
            "p90": float(np.percentile(error, 90)) if len(error) else math.nan,
            "ids": len(ids), "confirmed": int(seen.sum())}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--draws", type=int, default=24)
    p.add_argument("--first", type=int, default=0)
    p.add_argument("--estimators", nargs="+", default=["paper", "mean"])
    args = p.parse_args(argv)
    results = {e: [] for e in args.estimators}
    for seed in range(args.first, args.first + args.draws):
        d = draw(seed)
        frames = frames_of(d)
        truth = np.array([f[2][0] for f in frames])
        line = (f"{seed:3d} {d['n']}x{d['n']} pitch {d['pitch']:.2f} m, {d['snr_db']:4.1f} dB, "
                f"plate {d['width']:.2f} x {d['height']:.2f} m")
        with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            path = write_sequence(Path(tmp) / "walk.h5", iter(frames), fps=FPS)
            for e in args.estimators:
                r = track(path, e, truth)
                results[e].append(r)
                line += (f" | {e}: median {r['median']:.3f} p90 {r['p90']:.3f} m, "
                         f"{r['ids']} id(s), {r['confirmed']} frames confirmed")
        print(line, flush=True)
    print("\nper-draw median error (m): median / 90th percentile / worst over draws")
    for e, rows in results.items():
        m = np.array([r["median"] for r in rows])
        print(f"{e:8s} {np.nanmedian(m):.3f} / {np.nanpercentile(m, 90):.3f} / "
              f"{np.nanmax(m):.3f}")
    if len(results) == 2:
        a, b = (np.array([r["median"] for r in rows]) for rows in results.values())
        print(f"{args.estimators[1]} nearer on {int((b < a).sum())} of {len(a)} draws")
    return 0


if __name__ == "__main__":
    sys.exit(main())
