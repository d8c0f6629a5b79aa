"""One tracked sequence of `reproduce tracking` and what is measured on it: the per-frame,
filtered, fixed-lag and smoothed x-y errors of a target, the causal Cramer-Rao bound for its
path, and a table row that says whether the goal (RMS <= 0.5 x per frame, max <= 0.10 m) holds.
"""
from __future__ import annotations

import math

import numpy as np

import nlos_cl as nl
from nlos_cl.tracking import Tracker, bounds, simulate_sequence
from nlos_cl.tracking.options import grouped

from .cases import Common


def run(c: Common, setup, moving, estimator, *, n_frames, seed=0, static=(), background=None,
        max_tracks=1, noise=None):
    """[(SimFrame, measured positions, {id: filtered position}, measured x-y covariances)] per
    frame, the tracker, and {frame: [fixed-lag positions]} (Tracker.lagged(lag) as it was lag
    frames later). `background`: a function making a fresh BackgroundRemover."""
    axis = nl.default_time_axis(setup, c.dt_s)
    frames = simulate_sequence(setup, moving, n_frames=n_frames, fps=c.fps, static=static,
                               noise=noise or nl.AWGN(c.snr_db), seed=seed,
                               facet_size_m=c.facet_m, time_axis=axis)
    tracker, out, lagged = None, [], {}
    for fr in frames:
        if tracker is None:
            tracker = Tracker(fr.signals, c.grid, estimator=estimator, motion=c.motion,
                              background=background() if background else None,
                              max_tracks=max_tracks, frame_interval_s=1 / c.fps,
                              **grouped(**c.tracker))
        tracks = tracker.update(fr.signals, fr.t_s)
        out.append((fr, [m.position for m in tracker.last_measurements],
                    {t.id: t.position for t in tracks},
                    [_xy_covariance(m) for m in tracker.last_measurements]))
        for point in tracker.lagged(c.lag).values():
            lagged.setdefault(point.frame, []).append(point.position)
    return out, tracker, lagged


def _xy_covariance(m):
    """A Kalman measurement's x-y covariance (its R, min_sigma_m included); NaN, as a frame
    without one, where the measurement leaves x or y out (a fit that did not determine it: a
    plate of zero amplitude reports an infinite variance there)."""
    axes = list(m.axes)
    if 0 not in axes or 1 not in axes:
        return np.full((2, 2), np.nan)
    at = [axes.index(a) for a in (0, 1)]
    return m.R[np.ix_(at, at)]


def errors(c: Common, result, tracker, lagged):
    """x-y errors of target 0 from frame c.first on: per frame, filtered, fixed-lag, smoothed
    (the nearest of each; NaN where there is none)."""
    smoothed = {}
    for points in tracker.smooth().values():
        for point in points:
            smoothed.setdefault(point.frame, []).append(point.position)
    raw, trk, lag, smo = [], [], [], []
    for fr, meas, tracks, _ in result[c.first:]:
        truth = fr.truths[0][:2]
        near = lambda ps: min((np.linalg.norm(p[:2] - truth) for p in ps),  # noqa: E731
                              default=np.nan)
        raw.append(near(meas))
        trk.append(near(tracks.values()))
        lag.append(near(lagged.get(fr.index, [])))
        smo.append(near(smoothed.get(fr.index, [])))
    # the last `lag` frames get their fixed-lag estimate only from frames after the sequence's
    # end: left out of that column (not counted as missing)
    return np.array(raw), np.array(trk), np.array(lag[:len(lag) - c.lag]), np.array(smo)


def bound_ratio(c: Common, result, path) -> float:
    """The causal Cramer-Rao bound (nlos_cl.tracking.bounds) for a target known to follow
    `path` = (family, true parameters), with each frame's reported measurement covariance
    (the one nearest the truth), as a ratio to those covariances: sqrt(sum tr B_k / sum tr
    R_k) over the frames from c.first on. The best RMS ratio any causal tracker could expect."""
    family, params = path
    t = np.array([fr.t_s for fr, *_ in result])
    covs = []
    for fr, meas, _, cov in result:
        near = [np.linalg.norm(p[:2] - fr.truths[0][:2]) for p in meas]
        covs.append(cov[int(np.argmin(near))] if near else np.full((2, 2), np.nan))
    covs = np.array(covs)
    bound = bounds.causal_bound(family, params, t, covs)[c.first:]
    seen = np.all(np.isfinite(covs[c.first:]), axis=(1, 2))
    if not seen.any():
        return math.nan
    return math.sqrt(np.trace(bound[seen], axis1=1, axis2=2).sum()
                     / np.trace(covs[c.first:][seen], axis1=1, axis2=2).sum())


def rms(e) -> float:
    return float(np.sqrt(np.nanmean(np.square(e))))


def _peak(e) -> float:
    return float(np.nanmax(e)) if np.isfinite(e).any() else math.nan


def path_row(c: Common, case, raw, trk, lag, smo, bound=math.nan) -> dict:
    """A table row: RMS and max of each column; each ratio against the per-frame error of the
    same frames (the lag column is shorter); the goal per column. A frame where no track is near
    counts as missing, and a column with missing frames fails the goal."""
    row = {"case": case, "frames": len(trk), "frames_without_track": int(np.isnan(trk).sum()),
           "per_frame_rms_m": rms(raw), "per_frame_max_m": _peak(raw)}
    tracked = not np.all(np.isnan(trk))
    for name, e in (("filter", trk), ("lag", lag), ("smoother", smo)):
        ratio = rms(e) / rms(raw[:len(e)]) if tracked else math.nan
        peak = _peak(e) if tracked else math.nan
        row.update({f"{name}_rms_m": rms(e) if tracked else math.nan, f"{name}_max_m": peak,
                    f"ratio_{name}": ratio})
        row[f"goal_{name}"] = bool(tracked and ratio <= c.goal["ratio"]
                                   and peak <= c.goal["max_m"] and not np.isnan(e).any())
    row["causal_bound"] = bound if tracked else math.nan
    return row
