"""Where a default `nlos-cl track` spends each frame: per frame the count mode the tracker
chose (tracking.births: 'auto' cold selection or a fixed K), every Locator call (warm, cold,
the K+1 probe), the background's cost, and the frame's seconds; optionally cProfile's top.

    python scripts/track_profile.py SEQ.h5 [--frames N] [--profile] [--targets auto]

The tracker is nl.track_sequence's, with every default (the CLI's); the calls are counted by
wrapping the tracker's own methods in this script only."""
from __future__ import annotations

import argparse
import cProfile
import io
import json
import pstats
import time

import numpy as np


def instrument(tracker, log):
    """Wrap the tracker's locate, probe and background to record each frame's calls."""
    locate, probe = tracker._locate, tracker._one_more

    def timed_locate(sig, prior, within=None):
        t0 = time.perf_counter()
        est = tracker.estimator
        out = locate(sig, prior, within)
        log[-1]["calls"].append({"targets": getattr(est, "targets", None),
                                 "warm": prior is not None, "box": within is not None,
                                 "found": len(out[1]),
                                 "s": round(time.perf_counter() - t0, 4)})
        return out

    def timed_probe(sig, location, found):
        log[-1]["probe"] = True
        return probe(sig, location, found)

    tracker._locate, tracker._one_more = timed_locate, timed_probe
    if tracker.background is not None:
        bg = tracker.background

        class Timed:
            alpha = getattr(bg, "alpha", 0)

            def __call__(self, sig):
                t0 = time.perf_counter()
                out = bg(sig)
                log[-1]["background_s"] = round(time.perf_counter() - t0, 4)
                return out

            def __getattr__(self, name):
                return getattr(bg, name)
        tracker.background = Timed()


def run(path, frames=None, targets="auto", profile=False, top=25, live=False):
    import nlos_cl as nl
    from nlos_cl.tracking import read_sequence
    seq = read_sequence(path)
    t0 = time.perf_counter()
    tracker = nl.track_sequence(seq, targets=targets, on_note=lambda _: None).tracker
    setup_s = time.perf_counter() - t0
    log = []
    instrument(tracker, log)
    stop = len(seq) if frames is None else min(frames, len(seq))
    prof = cProfile.Profile() if profile else None
    errors = []
    for frame in seq.frames(0, stop):
        log.append({"frame": frame.index, "calls": [], "probe": False})
        t = time.perf_counter()
        if prof is not None and frame.index > 0:
            prof.enable()
        tracks = tracker.update(frame.histograms, frame.t_s)
        if prof is not None:
            prof.disable()
        log[-1]["s"] = round(time.perf_counter() - t, 4)
        log[-1]["tracks"] = [(t.id, t.status) for t in tracks]
        if live:
            print(json.dumps(log[-1]), flush=True)
        if frame.truths is not None and len(tracks):
            pos = np.array([t.position for t in tracks])
            errors.append([float(np.min(np.linalg.norm(pos - np.asarray(x), axis=1)))
                           for x in frame.truths])
    secs = np.array([f["s"] for f in log[1:]])
    summary = {"file": str(path), "frames": stop, "setup_s": round(setup_s, 3),
               "first_frame_s": log[0]["s"],
               "frames_per_s_median": round(1.0 / float(np.median(secs)), 2),
               "frames_per_s_mean": round(len(secs) / float(secs.sum()), 2),
               "s_per_frame_p10_p50_p90": [round(float(q), 4) for q in
                                           np.quantile(secs, [0.1, 0.5, 0.9])],
               "auto_frames": sum(any(c["targets"] == "auto" for c in f["calls"]) for f in log),
               "probe_frames": sum(f["probe"] for f in log),
               "cold_after_warm": sum(len(f["calls"]) > 1 and f["calls"][0]["warm"] and not
                                      f["probe"] for f in log),
               "background_s_median": float(np.median([f.get("background_s", 0.0)
                                                       for f in log]))}
    if prof is not None:
        out = io.StringIO()
        pstats.Stats(prof, stream=out).sort_stats("cumulative").print_stats(top)
        summary["profile"] = out.getvalue()
    return summary, log, errors


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("file")
    ap.add_argument("--frames", type=int)
    ap.add_argument("--targets", default="auto")
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--log", action="store_true", help="print every frame's calls")
    ap.add_argument("--code", help="a checkout whose nlos_cl to run")
    a = ap.parse_args()
    if a.code:
        import sys
        sys.path.insert(0, a.code)
    targets = a.targets if a.targets == "auto" else int(a.targets)
    summary, log, errors = run(a.file, a.frames, targets, a.profile, live=a.log)
    prof = summary.pop("profile", None)
    print(json.dumps(summary))
    if errors:
        e = np.array([min(x) for x in errors[5:]]) if len(errors) > 5 else np.array([])
        if e.size:
            print(f"nearest-track error after frame 5 (first truth): median {np.median(e):.4f}")
    if prof:
        print(prof)


if __name__ == "__main__":
    main()
