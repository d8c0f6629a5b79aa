"""The runs of `reproduce real`, one function per dataset: read it as `nlos-cl convert` does
(nl.read_dataset; the walk also through write_sequence / read_sequence, as `nlos-cl track`
reads it), locate or track with the library's defaults, time it, and compare with the truth
or reference the dataset ships. Each returns table rows (dicts) and the series its figure
needs; the page and figures are report's."""
from __future__ import annotations

import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

import nlos_cl as nl
from nlos_cl.core.geometry import farthest_points
from nlos_cl.core.histograms import reciprocal
from nlos_cl.localization.backprojection import backprojection_peak
from nlos_cl.localization.ranges import range_rules


def _timed(call):
    start = time.perf_counter()
    value = call()
    return value, time.perf_counter() - start


def _located(h, fit=None):
    """locate_capture's position with its defaults, or None where it detected nothing (noise:
    `nlos-cl locate` exits 3; the argmax of noise is no location); warnings (e.g. 'paired
    captures get the paper's argmax by default') are kept in the answer, not printed. fit: a
    dict given the answer's kind and misfit (`_fit_fields`)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        location = nl.locate_capture(h).points[0].location
    if fit is not None and location.detected:
        fit.update(_fit_fields(location.targets[0]))
    return location.position if location.detected else None


def _fit_fields(target) -> dict:
    """What answered (the model's shape, or the argmax and which fit it replaced) and the
    misfit ratio of the fit behind it (Birge ratio; counts: deviance per degree of freedom;
    the rejected fit's where the argmax replaced it): how well the model explains the capture
    (issue 57 asks it of every measured dataset)."""
    if target.fit is not None:
        return {"answer": target.fit.shape,
                "misfit_ratio": _round(target.fit.diagnostics.get("misfit_ratio"), 1)}
    rejected = (target.details or {}).get("rejected_fit") or {}
    shape = rejected.get("shape") or rejected.get("model")
    return {"answer": f"argmax ({shape} rejected)" if shape else "argmax",
            "misfit_ratio": _round(rejected.get("misfit_ratio"), 1)}


def ccsocr(cfg: dict, root: Path) -> dict:
    """The full scan and spread subsets of it: the located depth (our y) against 0.85-1.00 m."""
    full, read_s = _timed(lambda: nl.read_dataset(root / cfg["folder"]))
    low, high = cfg["goal"]["depth_m"]
    cases = [("full", full.n_detectors, full)] * bool(cfg["full"]) + [
        (f"{k} points", k, full.select(farthest_points(full.laser_spots, k)))
        for k in cfg["subsets"]] + [
        (f"{k} points, one laser (reciprocity)", k,
         reciprocal(full.select(farthest_points(full.laser_spots, k))))
        for k in cfg.get("reciprocal", [])]
    rows = []
    for name, count, h in cases:
        fit: dict = {"answer": None, "misfit_ratio": None}
        position, seconds = _timed(lambda: _located(h, fit))
        depth = None if position is None else float(position[1])
        rows.append({"case": name, "scan_points": count, "detected": position is not None,
                     "position_m": _r(position), "depth_m": _round(depth, 3), **fit,
                     "error_m": None if depth is None else
                     round(max(low - depth, depth - high, 0.0), 3),
                     "seconds": round(seconds, 2),
                     "met": bool(depth is not None and low <= depth <= high
                                 and seconds <= cfg["goal"]["max_s"])})
    return {"rows": rows, "read_s": round(read_s, 2)}


def lct(cfg: dict, root: Path) -> dict:
    """Each confocal scan: the located position against the backprojection's peak (depth)."""
    rows = []
    for name in cfg["files"]:
        h, read_s = _timed(lambda: nl.read_dataset(root / name))
        fit: dict = {"answer": None, "misfit_ratio": None}
        position, seconds = _timed(lambda: _located(h, fit))
        reference, bp_s = _timed(lambda: backprojection_peak(h, **cfg["backprojection"]))
        error = None if position is None else abs(float(position[1] - reference[1]))
        rows.append({"case": Path(name).stem, "detected": position is not None,
                     "position_m": _r(position), "reference_m": _r(reference), **fit,
                     "depth_error_m": _round(error, 3),
                     "seconds": round(seconds, 2), "read_s": round(read_s, 2),
                     "backprojection_s": round(bp_s, 1),
                     "met": bool(error is not None and position[1] > 0.1
                                 and error <= cfg["goal"]["depth_m"])})
    return {"rows": rows}


def keyhole(cfg: dict, root: Path) -> dict:
    """Each letter through `convert` then `track` (a sequence file; one confocal spot, so
    `nlos-cl track` follows the range: apps.track._range_main's steps with every default)
    against the stage's range: correlation, and RMS after the one constant offset that best
    aligns them; the frames' own measured ranges' RMS beside it."""
    from nlos_cl.tracking import read_sequence, write_sequence
    from nlos_cl.tracking.ranges import track_frames
    from nlos_cl.tracking.sequences import motion_for
    rows, series = [], {}
    for letter in cfg["letters"]:
        (frames, meta), read_s = _timed(lambda: nl.read_dataset(root / "keyhole" / letter))
        with tempfile.TemporaryDirectory() as tmp:
            path = write_sequence(Path(tmp) / f"{letter}.h5", frames, fps=meta.get("fps"))
            seq = read_sequence(path)
            points, seconds = _timed(lambda: track_frames(
                seq.frames(), h_s=nl.PAPER_H_S, motion=motion_for())[0])
        ours = np.array([p.range_m for p in points])
        measured = np.array([p.measured_m for p in points])
        stage = np.asarray(meta["stage_range_m"])
        offset = float(np.mean(ours - stage))
        corr = float(np.corrcoef(ours, stage)[0, 1])
        rms, rms_measured = _rms_after_offset(ours, stage), _rms_after_offset(measured, stage)
        series[letter] = (ours, stage, offset)
        lateral, rms_lateral = _letter_lateral(ours, meta)
        rules = {f"rms_{name}_m": round(_rms_after_offset(r, stage), 4)
                 for name, r in range_rules(frames, nl.PAPER_H_S).items()}
        rows.append({"case": letter, "exposures": len(frames),
                     "frames_detected": int(np.isfinite(measured).sum()),  # noise: none
                     "corr": round(corr, 3),
                     "rms_m": round(rms, 4), "rms_measured_m": round(rms_measured, 4),
                     "offset_m": round(offset, 3),
                     "letter_lateral_m": round(lateral, 3),
                     "rms_letter_lateral_m": round(rms_lateral, 4), **rules,
                     "seconds": round(seconds, 2), "read_s": round(read_s, 2),
                     "met": bool(corr >= cfg["goal"]["corr"] and rms <= cfg["goal"]["rms_m"])})
    return {"rows": rows, "series": series}


def _rms_after_offset(ours, stage) -> float:
    residual = np.asarray(ours) - np.asarray(stage)
    return float(np.sqrt(np.mean((residual - residual.mean()) ** 2)))


def _letter_lateral(ours, meta) -> tuple[float, float]:
    """A diagnosis, not the goal's measure: the stage truth is the range to the object grid's
    centre, but where each letter's bright middle sits on that 0.6 m grid is not documented.
    The lateral place (m, within the grid's half width) whose stage range, after one constant
    offset, best matches ours, and the RMS (m) then: what is left once the letter's place is
    known."""
    from scipy.optimize import minimize_scalar

    from nlos_cl.io.datasets.keyhole import stage_range_m
    x, z = np.asarray(meta["xpos_m"]), np.asarray(meta["zpos_m"])

    def rms(lateral):
        return _rms_after_offset(ours, stage_range_m(x, z, lateral))
    best = minimize_scalar(rms, bounds=(-0.3, 0.3), method="bounded",
                           options={"xatol": 1e-4})
    return float(best.x), rms(best.x)


def walk(cfg: dict, root: Path) -> dict:
    """The walk through `nlos-cl track`'s path (a sequence file; the Tracker the command
    builds with every default: nl.track_sequence), against the authors'
    particle-filter means on the top view (their X, Z; Y is the weakly seen vertical). Three
    rows from one run: the causal filter (the goal's), the fixed-lag estimate `--lag L` prints
    (L = cfg["lag_frames"] later frames used: real time with L frames of latency) and the
    offline `--smooth`, each of the longest-lived confirmed track."""
    from nlos_cl.tracking import read_sequence, write_sequence
    (frames, meta), read_s = _timed(lambda: nl.read_dataset(root / cfg["folder"]))
    frames = frames[:cfg["frames"]] if cfg["frames"] else frames
    lag = int(cfg["lag_frames"])
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the default's note on paired captures
        path = write_sequence(Path(tmp) / "walk.h5", frames, fps=meta["fps"])
        seq = read_sequence(path)
        tracker = nl.track_sequence(seq).tracker
        grid = tracker.grid
        ours, ids, per_frame = np.full((len(seq), 3), np.nan), [], []
        lagged, reported = np.full((len(seq), 3), np.nan), None
        for k, frame in enumerate(seq.frames()):
            tracks, seconds = _timed(lambda: tracker.update(frame.histograms, frame.t_s))
            per_frame.append(seconds)
            confirmed = [t for t in tracks if t.status == "confirmed"]
            ids.extend(t.id for t in tracks)
            if confirmed:  # the longest-lived confirmed track is the one reported
                best = max(confirmed, key=lambda t: len(t.history))
                ours[k], reported = seq.frame.from_internal(best.position), best.id
                _put(lagged, tracker.lagged(lag).get(best.id), seq.frame)
        for after in range(lag - 1, -1, -1):  # the last frames: with the later frames there are
            _put(lagged, tracker.lagged(after).get(reported), seq.frame)
        smoothed = np.full((len(seq), 3), np.nan)
        for point in tracker.smooth().get(reported, []):
            _put(smoothed, point, seq.frame)
    lagged[np.isnan(ours[:, 0])] = np.nan  # the frames the filter reported, for all three
    smoothed[np.isnan(ours[:, 0])] = np.nan
    reference = np.asarray(meta["reference_positions"])[:len(ours)]
    rows = [_walk_row(cfg, case, track, reference, ids, per_frame, grid, read_s)
            for case, track in (("walk", ours), (f"walk, fixed lag {lag} (--lag {lag})", lagged),
                                ("walk, smoothed (--smooth)", smoothed))]
    return {"rows": rows, "series": {"ours": ours, "reference": reference, "lagged": lagged}}


def _put(series, point, cframe) -> None:
    """A Smoothed point (or None) into its frame's row of `series`, in the file's frame."""
    if point is not None:
        series[point.frame] = cframe.from_internal(point.position)


def _walk_row(cfg, case, ours, reference, ids, per_frame, grid, read_s) -> dict:
    top = [0, 2]  # the file's (X, Z): the floor plane
    seen = ~np.isnan(ours[:, 0])
    distance = np.linalg.norm(ours[seen][:, top] - reference[seen][:, top], axis=1)
    fps = len(per_frame) / sum(per_frame)
    # both over the frames where ours exists (a step across a gap is not counted in either)
    both = np.where(seen[:, None], reference, np.nan)
    jitter_ours, jitter_pf = _jitter(ours[:, top]), _jitter(both[:, top])
    n_ids = len(set(ids))
    return {"case": case, "frames": len(per_frame), "frames_per_s": round(fps, 1),
            "frame_ms_median": round(1e3 * float(np.median(per_frame)), 1),
            "frame_ms_p10_p90": [round(1e3 * float(q), 1)
                                 for q in np.percentile(per_frame, [10, 90])],
            "track_ids": n_ids, "frames_confirmed": int(seen.sum()),
            "median_distance_to_pf_m": round(float(np.median(distance)), 3)
            if len(distance) else None,
            "jitter_ours_m": jitter_ours, "jitter_pf_m": jitter_pf,
            "roughness_ours_m": _jitter(ours[:, top], order=2),
            "roughness_pf_m": _jitter(both[:, top], order=2),
            "path_ours_m": _path(ours[:, top]), "path_pf_m": _path(both[:, top]),
            "grid_cells": int(np.prod(grid.shape)), "grid_step_m": round(grid.step[0], 4),
            "read_s": round(read_s, 2),
            "met": {"fps": bool(fps >= cfg["goal"]["fps"]),
                    "ids": bool(n_ids == cfg["goal"]["ids"]),
                    "smoother": bool(jitter_ours is not None and jitter_pf is not None
                                     and jitter_ours < jitter_pf)}}


def _jitter(top, order: int = 1) -> float | None:
    """order 1: the median distance (m) between consecutive frames' top-view positions, where
    both exist (the goal's measure: it counts the walker's own motion as well); order 2: the
    median length of the second difference x[k+1] - 2 x[k] + x[k-1] (roughness: a steady
    walk adds ~a dt^2, ~2 mm at 14 frames/s and 0.5 m/s^2, whatever its speed)."""
    steps = np.linalg.norm(np.diff(top, n=order, axis=0), axis=1)
    steps = steps[np.isfinite(steps)]
    return round(float(np.median(steps)), 4) if len(steps) else None


def _path(top) -> float:
    """The top-view path length (m) over consecutive frames where both exist."""
    steps = np.linalg.norm(np.diff(top, axis=0), axis=1)
    return round(float(np.sum(steps[np.isfinite(steps)])), 1)


def _r(v) -> list | None:
    return None if v is None else [round(float(x), 3) for x in v]


def _round(x, digits: int):
    """A finite number rounded, else None (nothing measured: the table says '-')."""
    return round(float(x), digits) if x is not None and np.isfinite(x) else None
