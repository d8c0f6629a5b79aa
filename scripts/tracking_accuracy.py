"""Tracking accuracy and throughput (issue 12's done-when table). Prints markdown tables.

    .venv/bin/python scripts/tracking_accuracy.py [--quick] [--only NAME ...] [--update-doc]
                                                  [--cold]

Sections: lines (straight/curved, paper and 8-spot layouts, paper and model estimators; the
causal filter and the offline RTS smoother), crossing (two targets, 8 spots, model estimator
with targets=2, 10 seeds), box (a static box with and without background removal), speed
(frames/s, 3 x 4,096 bins, 512^2 grid, host frames to track states), memory (peak RSS tracking
a 10,000-frame sequence file), synthetic (the constant-velocity filter alone on the bound's
line and circle with white 8 mm errors: what its process noise allows). --update-doc writes
each section's output into docs/tracking.md between its markers
(<!-- tracking_accuracy:NAME --> ... <!-- /tracking_accuracy:NAME -->).
--cold: trackers with warm_start=False (every model fit from the frame's data alone: the
numbers before warm starts, for comparison; not for --update-doc).
"""
from __future__ import annotations

import argparse
import contextlib
import io
import math
import os
import re
import resource
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

import nlos_cl as nl
from nlos_cl.physics.layouts import circle
from nlos_cl.localization.model import ModelEstimator
from nlos_cl.tracking import BackgroundRemover, ConstantVelocity, MovingTarget, SensorNoise, Tracker, Trajectory, read_sequence, simulate_sequence, write_sequence
from nlos_cl.tracking import bounds

FACET, DT, FPS, SNR_DB = 0.02, 10e-12, 10, 10
GRID = nl.Grid.from_ranges(x=(1.5, 5.5), y=(0.5, 4.5), step_m=0.01)
# Process noise from the motion model, one value for every case: targets that accelerate by up
# to A_MAX (the curved path's centripetal v^2 / R = 0.47^2 / 1.5 = 0.15 m/s^2; a walker who
# keeps pace). White acceleration of density q changes the velocity by ~sqrt(q T) over a frame
# interval T (Bar-Shalom, Li & Kirubarajan 2001, sec. 6.2.2), so q = A_MAX^2 T.
A_MAX = 0.15
MOTION = ConstantVelocity(accel_sigma=A_MAX * math.sqrt(1 / FPS))
# The same tracker settings in every case. max_birge_ratio: a fit that leaves twice the noise's
# variance unexplained is not used (a correct fit's Birge ratio scatters about 1 with sd ~0.25,
# docs/model-estimator.md; on this script's single-target frames it stays within 0.3-1.7).
# max_misses: a track may coast 2 s (20 frames) without a usable measurement; its position sd
# from the motion noise alone is then sqrt(q t^3 / 3) = 0.08 m, under half a 0.3 m target.
TRACKING = dict(max_birge_ratio=2.0, max_misses=20)
DOC = Path(__file__).resolve().parents[1] / "docs" / "tracking.md"


def layouts():
    return {"paper": nl.paper_setup(),
            "8-spot": nl.Setup(detector_spots=circle((-1.0, 0, 0), 0.5, 8))}


def bound_paths(span=5.0):
    """The two paths as families of nlos_cl.tracking.bounds with their true parameters, `span`
    s long: a line from (3, 1.5) to (4, 3), a quarter circle of 1.5 m around (2, 3)."""
    return {"straight": (bounds.line, (3.0, 1.5, 1.0 / span, 1.5 / span)),
            "curved": (bounds.circle, (2.0, 3.0, 1.5, 0.0, math.pi / 2 / span))}


def trajectories(span=5.0):
    """The two paths, `span` s long (50 frames at 10 fps; --quick runs their first 20 frames,
    at the same speed): the line's end points, 21 waypoints on the circle."""
    out = {}
    for (name, (family, params)), n in zip(bound_paths(span).items(), (2, 21)):
        t = np.linspace(0, span, n)
        out[name] = Trajectory(t, np.column_stack([family(params, t), np.zeros(n)]))
    return out


def run(setup, moving, estimator, *, n_frames, seed=0, static=(), background=None,
        max_tracks=1, noise=None):
    """[(SimFrame, measured positions, {id: filtered position})] per frame, the tracker, and
    {frame: [fixed-lag positions]} (Tracker.lagged(LAG) as it was LAG frames later)."""
    axis = nl.default_time_axis(setup, DT)
    frames = simulate_sequence(setup, moving, n_frames=n_frames, fps=FPS, static=static,
                               noise=noise or nl.AWGN(SNR_DB), seed=seed, facet_size_m=FACET,
                               time_axis=axis)
    tracker, out, lagged = None, [], {}
    for fr in frames:
        if tracker is None:
            tracker = Tracker(fr.signals, GRID, estimator=estimator, motion=MOTION,
                              background=background() if background else None,
                              max_tracks=max_tracks, frame_interval_s=1 / FPS, **TRACKING)
        tracks = tracker.update(fr.signals, fr.t_s)
        out.append((fr, [m.position for m in tracker.last_measurements],
                    {t.id: t.position for t in tracks},
                    [_xy_covariance(m) for m in tracker.last_measurements]))
        for point in tracker.lagged(LAG).values():
            lagged.setdefault(point.frame, []).append(point.position)
    return out, tracker, lagged


def errors(result, tracker, lagged, first=5):
    """x-y errors of target 0 after frame `first`: per frame, filtered, fixed-lag, smoothed
    (nearest)."""
    smoothed = {}
    for points in tracker.smooth().values():
        for point in points:
            smoothed.setdefault(point.frame, []).append(point.position)
    raw, trk, lag, smo = [], [], [], []
    for fr, meas, tracks, _ in result[first:]:
        truth = fr.truths[0][:2]
        near = lambda ps: min((np.linalg.norm(p[:2] - truth) for p in ps),  # noqa: E731
                              default=np.nan)
        raw.append(near(meas))
        trk.append(near(tracks.values()))
        lag.append(near(lagged.get(fr.index, [])))
        smo.append(near(smoothed.get(fr.index, [])))
    # the last LAG frames get their fixed-lag estimate only from frames after the sequence's
    # end: left out of that column (not counted as missing)
    return np.array(raw), np.array(trk), np.array(lag[:len(lag) - LAG]), np.array(smo)


def _xy_covariance(m):
    """A Kalman measurement's x-y covariance (its R, min_sigma_m included)."""
    at = [list(m.axes).index(a) for a in (0, 1)]
    return m.R[np.ix_(at, at)]


def bound_ratio(result, path, first=5):
    """The causal Cramer-Rao bound (nlos_cl.tracking.bounds) for a target known to follow
    `path` = (family, true parameters), with each frame's reported measurement covariance
    (the one nearest the truth), as a ratio to those covariances: sqrt(sum tr B_k / sum tr
    R_k) over the frames after `first`. The best RMS ratio any causal tracker could expect."""
    family, params = path
    t = np.array([fr.t_s for fr, *_ in result])
    covs = []
    for fr, meas, _, cov in result:
        near = [np.linalg.norm(p[:2] - fr.truths[0][:2]) for p in meas]
        covs.append(cov[int(np.argmin(near))] if near else np.full((2, 2), np.nan))
    covs = np.array(covs)
    bound = bounds.causal_bound(family, params, t, covs)[first:]
    seen = np.all(np.isfinite(covs[first:]), axis=(1, 2))
    if not seen.any():
        return math.nan
    return math.sqrt(np.trace(bound[seen], axis1=1, axis2=2).sum()
                     / np.trace(covs[first:][seen], axis1=1, axis2=2).sum())


def rms(e):
    return float(np.sqrt(np.nanmean(np.square(e))))


def _row(name, raw, trk, lag, smo, bound=math.nan):
    """A table row; a frame where no track (or measurement) is near counts as missing, and a
    case with missing frames fails the goal."""
    if np.all(np.isnan(trk)):
        return (f"| {name} | {rms(raw):.4f} / {np.nanmax(raw):.4f} | no track | no track | "
                f"no track | - | - | no / no / no |")
    # each column against the per-frame error of the same frames (the lag column is shorter)
    ratio = lambda e: rms(e) / rms(raw[:len(e)])  # noqa: E731
    ok = lambda e: (ratio(e) <= 0.5 and np.nanmax(e) <= 0.10  # noqa: E731
                    and not np.isnan(e).any())
    missing = f" ({np.isnan(trk).sum()} frames without a track)" if np.isnan(trk).any() else ""
    cells = " | ".join(f"{rms(e):.4f} / {np.nanmax(e):.4f}" for e in (lag, smo))
    ratios = " / ".join(f"{ratio(e):.2f}" for e in (trk, lag, smo))
    met = " / ".join("yes" if ok(e) else "no" for e in (trk, lag, smo))
    return (f"| {name} | {rms(raw):.4f} / {np.nanmax(raw):.4f} | {rms(trk):.4f} / "
            f"{np.nanmax(trk):.4f}{missing} | {cells} | {ratios} | {bound:.2f} | {met} |")


# Fixed-lag smoothing's latency (frames): Tracker.lagged(LAG), i.e. 0.5 s at 10 fps
LAG = 5
HEAD = (f"| per-frame RMS / max (m) | filter RMS / max (m) | fixed lag {LAG} RMS / max (m) | "
        "smoother RMS / max (m) | ratio filter / lag / smoother | causal bound | goal met "
        "filter / lag / smoother |")
SEP = "|---|---|---|---|---|---|---|---|"


def lines(quick):
    n = 20 if quick else 50
    print(f"\n| trajectory, layout, estimator {HEAD}\n{SEP}")
    for tname, traj in trajectories().items():
        for lname, setup in layouts().items():
            target = nl.Target(nl.rectangle(centre=traj.at(0), cell_m=FACET))
            for est in ("paper", "model"):
                res, tracker, lagged = run(setup, MovingTarget(target, traj), est,
                                           n_frames=n, seed=1)
                print(_row(f"{tname}, {lname}, {est}", *errors(res, tracker, lagged),
                           bound=bound_ratio(res, bound_paths()[tname])), flush=True)


def synthetic(quick):
    """The constant-velocity filter alone (Tracker.step, no estimator) on the two paths of the
    causal bound (bound_paths: 50 frames at 10 fps) measured with white 8 mm errors, seeds x
    process noises: what the motion model allows. Ratio: filter RMS / per-frame RMS after
    frame 5, pooled over the seeds."""
    from nlos_cl.tracking import kalman
    seeds, sigma, t = (5 if quick else 30), 0.008, np.arange(50) / FPS
    paths = bound_paths()
    layout = nl.simulate(nl.paper_scene(facet_size_m=0.05)).layout  # (only its geometry)
    print("\n| accel_sigma | " + " | ".join(f"{n}: filter / per frame" for n in paths)
          + " |\n|---|" + "---|" * len(paths))
    for accel in (0.005, 0.01, 0.02, 0.047, 0.07, 0.1):
        cells = []
        for family, params in paths.values():
            truth, filtered, measured = family(params, t), [], []
            for seed in range(seeds):
                rng = np.random.default_rng(seed)
                tracker = Tracker(layout, GRID, frame_interval_s=1 / FPS,
                                  motion=ConstantVelocity(accel_sigma=accel))
                for k, tk in enumerate(t):
                    z = truth[k] + sigma * rng.standard_normal(2)
                    m = kalman.Measurement(np.arange(2), z, sigma ** 2 * np.eye(2), np.r_[z, 0])
                    (track,) = tracker.step([m], tk)
                    if k >= 5:
                        filtered.append(np.sum((track.position[:2] - truth[k]) ** 2))
                        measured.append(np.sum((z - truth[k]) ** 2))
            cells.append(f"{math.sqrt(np.mean(filtered) / np.mean(measured)):.2f}")
        print(f"| {accel} | " + " | ".join(cells) + " |", flush=True)


def crossing(quick):
    n, seeds = (16, 3) if quick else (20, 10)
    setup = layouts()["8-spot"]
    a = Trajectory([0, n / FPS], [[2.5, 2.0, 0], [3.5, 3.0, 0]])
    b = Trajectory([0, n / FPS], [[2.5, 3.0, 0], [3.5, 2.0, 0]])
    square = lambda p: nl.Target(nl.rectangle(0.3, 0.3, centre=p, cell_m=FACET))  # noqa: E731
    kept, t0 = 0, time.perf_counter()
    for seed in range(seeds):
        pair = [MovingTarget(square(a.at(0)), a), MovingTarget(square(b.at(0)), b)]
        res, _, _ = run(setup, pair, ModelEstimator(targets=2), n_frames=n, seed=seed,
                        max_tracks=2)
        ids = [_nearest(res[3], k) for k in (0, 1)]
        last = [_nearest(res[-1], k) for k in (0, 1)]
        ok = ids[0] != ids[1] and ids == last and None not in ids
        kept += ok
        print(f"- seed {seed}: track ids nearest the two targets at frame 3 {ids}, at the end "
              f"{last}: {'kept' if ok else 'LOST'}", flush=True)
    print(f"\ncrossing (8 spots, model estimator, targets=2, {n} frames): identities kept in "
          f"**{kept} of {seeds}** seeds ({(time.perf_counter() - t0) / seeds / n:.2f} s/frame)")


def _nearest(entry, k, radius=0.15):
    fr, _, tracks, _ = entry
    best = min(tracks.items(), key=lambda kv: np.linalg.norm(kv[1][:2] - fr.truths[k][:2]),
               default=(None, None))
    ok = best[0] is not None and np.linalg.norm(best[1][:2] - fr.truths[k][:2]) < radius
    return best[0] if ok else None


def box(quick):
    n = 20 if quick else 50
    setup = layouts()["paper"]
    traj = trajectories()["straight"]
    moving = MovingTarget(nl.Target(nl.rectangle(centre=traj.at(0), cell_m=FACET)), traj)
    clutter = nl.Target(nl.box((0.5, 0.5, 1.0), centre=(2.0, 1.0, 0), cell_m=FACET))
    axis = nl.default_time_axis(setup, DT)
    # the sensor's noise floor: AWGN's 10 dB level for the target-only first frame, then fixed
    first = next(simulate_sequence(setup, moving, n_frames=1, fps=FPS, facet_size_m=FACET,
                                   time_axis=axis))
    noise = SensorNoise.from_snr(first.signals, SNR_DB)
    reference = _reference(setup, clutter, axis, noise)
    print(f"\n| scene, estimator {HEAD}\n{SEP}")
    cases = [("no box", (), None), ("box, no removal", (clutter,), None),
             ("box, reference (mean of 100 target-free frames)", (clutter,),
              lambda: BackgroundRemover(reference, clip=False)),
             ("box, running mean a=0.1", (clutter,), lambda: BackgroundRemover(alpha=0.1,
                                                                               clip=False))]
    for est in ("paper", "model"):
        for name, static, bg in cases:
            res, tracker, lagged = run(setup, moving, est, n_frames=n, seed=1, static=static,
                                       background=bg, noise=noise)
            print(_row(f"{name}, {est}", *errors(res, tracker, lagged),
                       bound=bound_ratio(res, bound_paths()["straight"])), flush=True)


def _reference(setup, clutter, axis, noise, frames=100):
    """A target-free capture as a sensor records it: the mean of `frames` noisy frames of the
    clutter alone (10 s at 10 fps). Its noise, 1/sqrt(frames) of a frame's, is the same in
    every frame it is subtracted from, so no filter averages it away: kept small."""
    sig = nl.simulate(nl.Scene(setup, clutter, FACET), axis)
    mean = sum(noise.apply(sig, 1000 + k).histograms().data for k in range(frames)) / frames
    return sig.histograms().with_data(mean)


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
    """Peak RSS while tracking a long file: first with max_history=1000 (bounded history and
    smoothing record), then the default (both kept whole). ru_maxrss is the process's peak, so
    the bounded run goes first."""
    n = 1000 if quick else 10_000
    frames = stream_frames()
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "long.h5")
        t0 = time.perf_counter()
        write_sequence(path, ((k / 100, frames[k % 8]) for k in range(n)))
        size = os.path.getsize(path)
        print(f"\nmemory: wrote {n} frames ({size / 2**20:.0f} MiB) in "
              f"{time.perf_counter() - t0:.1f} s", flush=True)
        for history in (n // 10, None):
            marks, rate = _track_file(read_sequence(path), n, history)
            print(f"- max_history={history}: peak RSS (MiB) after " + ", ".join(
                f"{k} frames: {v / 1024:.0f}" for k, v in marks.items())
                + f" ({rate:.0f} frames/s on a 128^2 grid)", flush=True)


def _track_file(seq, n, max_history):
    tracker = Tracker(seq, nl.Grid((2.0, 0.5, 0.0), (1 / 32, 1 / 32, 0.01), (128, 128, 1)),
                      estimator="paper", motion=MOTION, max_history=max_history)
    marks, t0 = {}, time.perf_counter()
    for frame in seq:
        tracker.update(frame.histograms, frame.t_s)
        if frame.index + 1 in (n // 10, n // 2, n):
            marks[frame.index + 1] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return marks, n / (time.perf_counter() - t0)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--only", nargs="*", default=None,
                   choices=["lines", "crossing", "box", "speed", "memory", "synthetic"])
    p.add_argument("--update-doc", action="store_true",
                   help="write each section's output into docs/tracking.md at its markers")
    p.add_argument("--cold", action="store_true",
                   help="no warm starts: every model fit from the frame's data alone")
    args = p.parse_args(argv)
    if args.cold:
        TRACKING["warm_start"] = False
    warnings.simplefilter("ignore")  # collinear spots: the model estimator's height warning
    print(f"device: {nl.resolve_backend().name}; {os.cpu_count()} CPU cores")
    for name in args.only or ["speed", "memory", "lines", "synthetic", "box", "crossing"]:
        t0 = time.perf_counter()
        buffer = io.StringIO()
        with contextlib.redirect_stdout(_Tee(sys.stdout, buffer)):
            globals()[name](args.quick)
        print(f"({name}: {time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
        if args.update_doc:
            _write_section(name, buffer.getvalue().strip())


class _Tee:
    def __init__(self, *streams):
        self.streams = streams

    def write(self, text):
        for s in self.streams:
            s.write(text)

    def flush(self):
        for s in self.streams:
            s.flush()


def _write_section(name, text):
    """Replace what docs/tracking.md holds between this section's markers."""
    doc = DOC.read_text()
    pattern = re.compile(rf"(<!-- tracking_accuracy:{name} -->\n)(?:.*?\n)?(<!-- /tracking_"
                         rf"accuracy:{name} -->)", re.S)
    if not pattern.search(doc):
        sys.exit(f"docs/tracking.md has no markers for {name}: add <!-- tracking_accuracy:"
                 f"{name} --> and <!-- /tracking_accuracy:{name} --> where it should go")
    DOC.write_text(pattern.sub(lambda m: m.group(1) + text + "\n" + m.group(2), doc))


if __name__ == "__main__":
    main()
