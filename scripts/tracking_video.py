"""The tracking notebook's scene (notebooks/tracking.ipynb, full setting) as a video: a
person-sized box walks an L past a static box, 60 frames at 10 fps, 8 wall spots, 10 dB; the
sequence and the target-free room are written to OUT, then tracked by the command line with
the model estimator and the room subtracted, the video drawn by `nlos-cl track --video`.

    .venv/bin/python scripts/tracking_video.py OUT_DIR [--video docs/tracking/walk.gif]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import nlos_cl as nl
from nlos_cl.physics import layouts
from nlos_cl.io.ytal.capture import write_capture
from nlos_cl.tracking import MovingTarget, Trajectory, simulate_sequence, write_sequence


def scene(out: Path, n_frames=60, fps=10):
    setup = nl.paper_setup(detector_spots=layouts.circle([-1, 0, 0], 0.5, 8))
    axis = nl.default_time_axis(setup, 10e-12)
    person = nl.Target(nl.box((0.2, 0.45, 1.7), centre=(3.0, 1.5, 0.0), cell_m=0.05))
    duration = (n_frames - 1) / fps
    path = Trajectory([0.0, duration / 2, duration],
                      [[3.0, 1.5, 0.0], [3.0, 3.0, 0.0], [4.5, 3.0, 0.0]])
    clutter = nl.Target(nl.box((0.5, 0.5, 1.0), centre=(1.8, 3.5, 0.0), cell_m=0.05))
    frames = simulate_sequence(setup, [MovingTarget(person, path)], static=[clutter],
                               n_frames=n_frames, fps=fps, time_axis=axis, noise=nl.AWGN(10),
                               seed=7, facet_size_m=0.05)
    write_sequence(out / "walk.h5", frames, fps=fps, force=True)
    room = nl.simulate(nl.Scene(setup, clutter, 0.05), axis)  # the room before the walk
    write_capture(out / "room.h5", room.histograms(), force=True)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", type=Path)
    p.add_argument("--video", default=None, help="default: OUT/walk.gif")
    args = p.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    scene(args.out)
    video = args.video or str(args.out / "walk.gif")
    cmd = [sys.executable, "-m", "nlos_cl.apps.cli", "track", str(args.out / "walk.h5"), "--json",
           "--estimator", "model", "--background", str(args.out / "room.h5"),
           "--region", "-6", "-0.5", "-0.5", "0.5", "0.3", "5", "--step", "0.05",
           "--video", video, "--force", "--no-progress"]
    lines = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout.splitlines()
    print(f"{len(lines)} frames tracked; last: {json.loads(lines[-1])['tracks'][:1]}")
    print("video:", video)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
