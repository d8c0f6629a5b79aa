"""Default `nlos-cl track` on random draws: speed and accuracy, for before/after comparisons.

    python scripts/track_draws.py walks --draws 0-19 [--code DIR] [--out rows.jsonl]
    python scripts/track_draws.py crossings --draws 0-19
    python scripts/track_draws.py files A.h5 B.h5 ...        (frames/s only, no truths)

walks: a walker (a plate or a person) past 1-2 static boxes or cabinets, the scenario suite's
clutter family (nlos-cl reproduce scenarios) with one mover and 40 frames (the suite's 12 are
too few to learn static returns); scored as the suite scores it: per frame after frame 5 the
confirmed, non-static tracks matched to the mover, the median of its error; and whether a track
on the furniture was reported as a mover. crossings: reproduce draws' crossing draws, tracked
with the targets NOT told (the default 'auto'), scored by cross_run.measure (one id per target
after frame 5, RMS). Sequence files are cached under /tmp/h4/draws. Every run uses
nl.track_sequence with every default (the CLI's); --code DIR runs another checkout's package
(put on sys.path first) to compare on the same files. frames/s: Tracker.update after the first
frame, median and quartiles of the per-frame seconds."""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np

CACHE = Path("/tmp/h4/draws")


def _walk_cfg():
    from nlos_cl.apps.reproduce.scenarios import draws as sd
    cfg = sd.config()
    cfg["families"] = ["clutter"]
    cfg["clutter"] = dict(cfg["clutter"], movers=[1], frames=40)
    return cfg


def walk_file(i: int):
    from nlos_cl.apps.reproduce.scenarios import draws as sd, run as sr
    cfg = _walk_cfg()
    d = sd.draw(i, cfg=cfg)
    folder = CACHE / f"walk{i}"
    path = folder / "seq.h5"
    if not path.exists():
        folder.mkdir(parents=True, exist_ok=True)
        out, why = sr.simulate(d, cfg, folder)
        if out is None:
            raise RuntimeError(why)
    return path, d, cfg, folder


def cross_file(i: int):
    from nlos_cl.simulation.draws import families
    from nlos_cl.apps.reproduce.draws import cross_run
    d = families.draw("crossings", i)
    path = CACHE / f"cross{i}.h5"
    if not path.exists():
        CACHE.mkdir(parents=True, exist_ok=True)
        cross_run.write_frames(d, path)
    return path, d


def tracked(path):
    """Every frame's live tracks (id, status, static, position (ours)), measurements, the
    update times."""
    import nlos_cl as nl
    from nlos_cl.tracking import read_sequence
    from nlos_cl.tracking.static import holds_still
    seq = read_sequence(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        tracker = nl.track_sequence(seq, on_note=lambda _: None).tracker
        setup = time.perf_counter() - t0
        frames, secs = [], []
        for frame in seq.frames(0, len(seq)):
            t = time.perf_counter()
            tracks = tracker.update(frame.histograms, frame.t_s)
            secs.append(time.perf_counter() - t)
            frames.append({"tracks": {tr.id: np.asarray(tr.position, float) for tr in tracks},
                           "status": {tr.id: (tr.status, holds_still(tr)) for tr in tracks},
                           "measured": [np.asarray(m.position, float)
                                        for m in tracker.last_measurements],
                           "truths": None if frame.truths is None else
                           np.asarray(frame.truths, float)})
    return frames, secs, setup, seq


def speed(secs) -> dict:
    later = np.asarray(secs[1:])
    q = np.quantile(later, [0.25, 0.5, 0.75])
    return {"fps_median": round(1 / q[1], 2), "fps_q25_q75": [round(1 / q[2], 2),
                                                               round(1 / q[0], 2)],
            "fps_mean": round(len(later) / later.sum(), 2), "first_s": round(secs[0], 3),
            "total_s": round(float(np.sum(secs)), 2)}


def score_walk(i: int) -> dict:
    from nlos_cl.apps.reproduce.scenarios import run as sr
    path, d, cfg, folder = walk_file(i)
    frames, secs, setup, seq = tracked(path)
    truths = sr.truths_of(d, cfg, folder)  # the file's frame
    errors, furniture_as_mover, ids = [], 0, set()
    statics = [o for o in d["objects"] if o["role"] == "furniture"]
    furn = np.array([o["centre"] for o in statics], float)
    for k, (_, shares) in truths.items():
        fr = frames[k]
        if shares[0] < cfg["lit_share"]:
            continue  # the walker shadowed: not scored (as the suite)
        walker = fr["truths"][0]  # ours, as the tracks
        mids = [tid for tid, (st, still) in fr["status"].items()
                if st == "confirmed" and not still]
        if not mids:
            errors.append(math.inf)
            continue
        gaps = [float(np.linalg.norm(fr["tracks"][tid] - walker)) for tid in mids]
        errors.append(min(gaps))
        ids.add(mids[int(np.argmin(gaps))])
        for tid in mids:  # a mover's track nearer the furniture than the walker
            p = fr["tracks"][tid]
            if len(furn) and np.min(np.linalg.norm(furn - p, axis=1)) < \
                    min(0.5, float(np.linalg.norm(walker - p))):
                furniture_as_mover += 1
    e = np.asarray(errors)
    return {"kind": "walk", "index": i, "median_m": round(float(np.median(e)), 4),
            "max_m": round(float(np.max(e)), 4), "ids": len(ids),
            "furniture_as_mover_frames": furniture_as_mover, "setup_s": round(setup, 2),
            **speed(secs)}


def score_cross(i: int) -> dict:
    from nlos_cl.apps.reproduce.draws import cross_run
    path, d = cross_file(i)
    frames, secs, setup, _ = tracked(path)
    m = cross_run.measure(frames, d["frames"]["first_frame"], 0.15)
    return {"kind": "cross", "index": i, "ids_ok": bool(m["ids_ok"]), "rms_m": m["rms_m"],
            "births": m["births"], "merged": m["merged_frames"], "setup_s": round(setup, 2),
            **speed(secs)}


def score_file(path) -> dict:
    frames, secs, setup, _ = tracked(path)
    return {"kind": "file", "file": str(path), "setup_s": round(setup, 2), **speed(secs),
            "ids": sorted({tid for f in frames for tid in f["tracks"]})}


def indices(text: str) -> list:
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("what", choices=["walks", "crossings", "files", "make"])
    ap.add_argument("paths", nargs="*")
    ap.add_argument("--draws", default="0-19")
    ap.add_argument("--code", help="a checkout whose nlos_cl to run")
    ap.add_argument("--out")
    a = ap.parse_args()
    if a.code:
        sys.path.insert(0, a.code)
    import nlos_cl
    print("code:", nlos_cl.__file__, file=sys.stderr)
    if a.what == "make":
        for i in indices(a.draws):
            walk_file(i)
            cross_file(i)
        return
    jobs = ([(score_file, p) for p in a.paths] if a.what == "files" else
            [(score_walk if a.what == "walks" else score_cross, i) for i in indices(a.draws)])
    out = open(a.out, "a") if a.out else None
    for fn, arg in jobs:
        try:
            row = fn(arg)
        except Exception as exc:  # noqa: BLE001 - a row says so
            row = {"arg": str(arg), "failed": f"{type(exc).__name__}: {exc}"[:300]}
        row["code"] = a.code or "HEAD"
        line = json.dumps(row)
        print(line, flush=True)
        if out:
            out.write(line + "\n")
            out.flush()


if __name__ == "__main__":
    main()
