"""One `crossings` draw of `reproduce draws`, run: its frames simulated with nlos_cl's forward
model (simulate_sequence, AWGN at the draw's SNR) and written as a sequence file, then tracked
as `nlos-cl track FILE --targets 2` tracks it: nl.track_sequence with every default but the
targets, as the CLI builds it, so the default estimator (the model fit, warm-started from
the tracks), its search region, sigma and motion noise. Nothing here tunes the tracker.

Per draw one row (cross_report reads it): from first_frame on, per target the track
nearest it in each frame (every live track, as `nlos-cl track` reports them) and how many
distinct ids those were, the RMS of that track's 3-D (and x-y) distance, and what went wrong
where it did: births, tracks lost, frames where both targets' nearest track was the same one
(a merged blob), frames with fewer than two measurements, ids taken over from the other
target (swaps). frames/s counts Tracker.update alone, after the first frame (which builds the
kernels and plans, timed apart as building the tracker is): not the simulation, not the file's reads."""
from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

import nlos_cl as nl

from ....simulation.draws import families
from ....simulation.draws.scenes import mesh_of
from ..common import Settings


def write_frames(d: dict, path: Path) -> float:
    """Simulate the draw's frames into a sequence file at `path`; the seconds it took."""
    from nlos_cl.tracking import MovingTarget, Trajectory, simulate_sequence, write_sequence
    f = d["frames"]
    span_s = (f["frames"] - 1) / f["fps"]
    setup = nl.paper_setup(detector_spots=np.asarray(d["layout"]["spots"], float))
    moving = [MovingTarget(nl.Target(mesh_of(t, f["facet_m"])),
                           Trajectory([0.0, span_s], t["path"])) for t in d["targets"]]
    start = time.perf_counter()
    frames = simulate_sequence(setup, moving, n_frames=f["frames"], fps=f["fps"],
                               noise=nl.AWGN(d["snr_db"]), seed=d["noise_seed"],
                               facet_size_m=f["facet_m"],
                               time_axis=nl.default_time_axis(setup, f["dt_s"]))
    write_sequence(path, frames, fps=f["fps"])
    return time.perf_counter() - start


def track_file(path: Path, targets: int = 2) -> dict:
    """`nlos-cl track PATH --targets N`'s tracker (nl.track_sequence's) on the file, frame by
    frame: per frame {id: position} of the live tracks, the measurement count and the truths;
    the times."""
    from nlos_cl.tracking import read_sequence
    seq = read_sequence(path)
    start = time.perf_counter()
    tracker = nl.track_sequence(seq, targets=targets, backend=nl.resolve_backend(None)).tracker
    setup_s, update_s, frames = time.perf_counter() - start, [], []
    for frame in seq.frames(0, len(seq)):
        start = time.perf_counter()
        tracks = tracker.update(frame.histograms, frame.t_s)
        update_s.append(time.perf_counter() - start)
        frames.append({"tracks": {t.id: np.asarray(t.position, float) for t in tracks},
                       "measured": [np.asarray(m.position, float)
                                    for m in tracker.last_measurements],
                       "truths": np.asarray(frame.truths, float)})
    return {"frames": frames, "setup_s": setup_s, "update_s": update_s}


def _nearest(tracks: dict, truth) -> tuple:
    """(id, 3-D distance, x-y distance) of the track nearest `truth`; (None, nan, nan)."""
    if not tracks:
        return None, math.nan, math.nan
    tid = min(tracks, key=lambda k: np.linalg.norm(tracks[k] - truth))
    gap = tracks[tid] - truth
    return tid, float(np.linalg.norm(gap)), float(np.linalg.norm(gap[:2]))


def _rms(e) -> float:
    e = np.asarray(e, float)
    return float(np.sqrt(np.mean(e ** 2))) if e.size and np.isfinite(e).all() else math.nan


def measure(frames, first: int, failure_m: float) -> dict:
    """The row's numbers from the tracked frames (track_file's), counted from `first` on."""
    counted = frames[first:]
    near = [[_nearest(fr["tracks"], fr["truths"][k]) for fr in counted] for k in (0, 1)]
    ids = [[n[0] for n in per] for per in near]
    kept = [sorted({i for i in per if i is not None}) for per in ids]
    missing = sum(i is None for per in ids for i in per)
    ok = (missing == 0 and all(len(k) == 1 for k in kept) and kept[0] != kept[1])
    # a swap: a target's nearest track is one that was the other target's before
    swaps = sum(any(i in ids[1 - k][:j] for j, i in enumerate(ids[k]) if i is not None
                    and i != ids[k][0]) for k in (0, 1))
    born = sorted({tid for fr in frames for tid in fr["tracks"]})
    last = frames[-1]["tracks"]
    errors = [[n[1] for n in per] for per in near]
    rms = [_rms(e) for e in errors]
    worst_frame = max((e for per in errors for e in per if math.isfinite(e)), default=math.nan)
    return {
        "ids_ok": ok, "ids_a": " ".join(map(str, kept[0])), "ids_b": " ".join(map(str, kept[1])),
        "missing_frames": missing,
        "rms_a_m": _round(rms[0]), "rms_b_m": _round(rms[1]),
        "rms_m": _round(max(rms) if all(math.isfinite(r) for r in rms) else math.nan),
        "rms_xy_m": _round(max(_rms([n[2] for n in per]) for per in near)),
        "max_m": _round(worst_frame),
        "frames_beyond": sum(e > failure_m for per in errors for e in per if math.isfinite(e)),
        "births": len(born), "lost": sum(tid not in last for tid in born),
        "max_live": max(len(fr["tracks"]) for fr in frames),
        "merged_frames": sum(a is not None and a == b for a, b in zip(*ids)),
        "under_two_measured": sum(len(fr["measured"]) < 2 for fr in counted),
        "swaps": swaps}


def live_ids(frames) -> str:
    """Per frame the live track ids and the measurement count, `ids/measured` (e.g. "1.2/2";
    "-" for none): what a failed row needs to see births, deaths and merges at a glance."""
    return " ".join(f"{'.'.join(map(str, fr['tracks'])) or '-'}/{len(fr['measured'])}"
                    for fr in frames)


def _round(v: float) -> float:
    return round(v, 5) if math.isfinite(v) else math.nan


def describe(d: dict) -> dict:
    """The draw's columns (the other families' names where they mean the same)."""
    c, f = d["crossing"], d["frames"]
    return {"family": d["family"], "sub": "plate", "index": d["index"],
            "master_seed": d["master_seed"], "layout": d["layout"]["kind"],
            "spots": len(d["layout"]["spots"]), "shapes": "plate plate", "k_true": 2,
            "snr_db": d["snr_db"], "truths": " ; ".join(
                " ".join(f"{v:.3f}" for v in t["path"][0] + t["path"][1]) for t in d["targets"]),
            "mismatch": "", "frames": f["frames"], "turn_deg": c["turn_deg"],
            "closest_m": c["closest_m"], "offset_s": c["offset_s"],
            "crossing_frame": round(min(c["fractions"]) * (f["frames"] - 1)),
            "sizes": " ; ".join(" ".join(f"{v:g}" for v in t["size"]) for t in d["targets"])}


def run(d: dict, s: Settings, failure_m: float | None = None) -> list[dict]:
    """The draw simulated and tracked: its one row. The frames' bins and facets are the draw's
    own (draws.yaml crossings), not `s`'s; a tracker that fails is a row, not a crash."""
    failure_m = families.config()["failure_m"] if failure_m is None else failure_m
    row = {**describe(d), "estimator": "track default"}
    with tempfile.TemporaryDirectory(prefix="nlos-cl-crossing-") as tmp:
        path = Path(tmp) / "crossing.h5"
        row["sim_s"] = round(write_frames(d, path), 3)
        start = time.perf_counter()
        try:
            tracked = track_file(path)
        except Exception as exc:  # the table says so, the run goes on
            return [{**row, "failed": f"{type(exc).__name__}: {str(exc)[:100]}",
                     "ids_ok": False, "rms_m": math.nan,
                     "seconds": round(time.perf_counter() - start, 3)}]
    later = tracked["update_s"][1:]
    row.update(measure(tracked["frames"], d["frames"]["first_frame"], failure_m))
    row.update(frames_per_s=round(len(later) / sum(later), 3) if later else math.nan,
               first_frame_s=round(tracked["update_s"][0], 3),
               setup_s=round(tracked["setup_s"], 3),
               seconds=round(time.perf_counter() - start, 3), failed="",
               live=live_ids(tracked["frames"]))
    return [row]
