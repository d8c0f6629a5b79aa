"""The consumer-nlos authors' particle filter as a timed peer (run by scripts/pf_peer.sh inside
its venv .venv-pf, torch on the CPU).

1. Copies the peer's code (../shared/peers/consumer-nlos, unmodified) into a temporary folder,
   links the walk's frames in as captured_data/st_spad_person_tracking (as its
   configs/tracking.yaml expects) and runs `python tracking.py` there: wall time, and the time of
   its particle-filter loop alone (its progress bar's elapsed time).
   Its per-frame particle means (results/.../particles.pth) go to OUT/pf_estimates.json.
2. Runs `nlos-cl convert` and `nlos-cl track --json` (nlos_cl's venv) on the same frames,
   timed the same way.
3. Prints a table: frames/s of each (whole program, and frame loop alone: each one's own
   progress bar), the ratios, and each estimate's median top-view distance
   to the particle means that ship with the dataset (the authors' own run: accuracy is compared
   against those; this run of their filter is random and is for timing) and its jitter.
   The timings go to docs/results/performance/performance-pf-peer.json, which `nlos-cl bench`
   reports.
Usage: pf_peer.sh [--out DIR] [--frames N] [--json PATH]
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
NLOS_PY = os.environ.get("NLOS_CL_PYTHON", str(ROOT / ".venv" / "bin" / "python"))
DATA = Path(os.environ.get("NLOS_CL_REALDATA", ROOT.parent / "shared" / "realdata"))
PEERS = Path(os.environ.get("NLOS_CL_PEERS", ROOT.parent / "shared" / "peers"))
WALK = DATA / "consumer-nlos" / "st_spad_person_tracking"
LOOP_BAR = re.compile(r"Particle Filtering: 100%[^\[]*\[(\d+):(\d+)<")
OUR_BAR = re.compile(r"track: 100%[^\[]*\[(\d+):(\d+)<")  # nlos-cl track's own progress bar
PEER_JSON = ROOT / "docs" / "results" / "performance" / "performance-pf-peer.json"  # bench reads it
TOP = [0, 2]  # the authors' (X, Z): the floor plane (Y is the weakly seen vertical)


def _frames(n: int | None) -> list[Path]:
    files = sorted(WALK.glob("volume_*.npz"))
    return files[:n] if n else files


def run_peer(tmp: Path, files: list[Path]) -> dict:
    """tracking.py in a copy of the peer, on `files`; its times and per-frame particle means."""
    import torch
    work = tmp / "peer"
    shutil.copytree(PEERS / "consumer-nlos", work)
    data = work / "captured_data" / "st_spad_person_tracking"
    data.mkdir(parents=True)
    for f in files:
        (data / f.name).symlink_to(f)
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "tracking.py"], cwd=work, capture_output=True,
                          text=True, env={**os.environ, "MPLBACKEND": "Agg"})
    wall = time.perf_counter() - start
    results = work / "results" / "st_spad_person_tracking"
    # its last step writes an .mp4 of plots; where opencv has no H.264 encoder that step fails
    # after the particles are saved: the tracking itself is complete, so it counts
    if proc.returncode != 0 and not (results / "particles.pth").is_file():
        raise SystemExit(f"pf_peer: the peer failed (exit {proc.returncode}):\n"
                         f"{proc.stderr[-2000:]}")
    if proc.returncode != 0:
        print("pf_peer: the peer's closing video step failed (no H.264 encoder); its "
              "particles were saved before it")
    # its particle-filter loop alone: the elapsed time of its tqdm bar (whole seconds; its log
    # lines carry no time stamps)
    bars = LOOP_BAR.findall(proc.stderr)
    loop = 60.0 * int(bars[-1][0]) + int(bars[-1][1]) if bars else float("nan")
    saved = torch.load(results / "particles.pth", weights_only=False)
    means = np.array([np.asarray(p).reshape(-1, 3).mean(axis=0) for p in saved["particles"]])
    return {"wall_s": wall, "loop_s": loop, "frames": len(means), "means": means}


def run_nlos_cl(tmp: Path, files: list[Path]) -> dict:
    """nlos-cl convert + track --json on the same frames: wall time of track, and the longest
    confirmed track's position per frame (the file's frame: the authors' axes)."""
    folder = tmp / "walk"
    folder.mkdir()
    for f in files:
        (folder / f.name).symlink_to(f)
    seq = tmp / "walk.h5"
    cli = [NLOS_PY, "-m", "nlos_cl.apps.cli"]
    subprocess.run([*cli, "convert", str(folder), "--out", str(seq)], check=True,
                   capture_output=True)
    start = time.perf_counter()
    proc = subprocess.run([*cli, "track", str(seq), "--json"], check=True,
                          capture_output=True, text=True)
    wall = time.perf_counter() - start
    # its frame loop alone, read as the peer's is: its progress bar's elapsed whole seconds
    bars = OUR_BAR.findall(proc.stderr)
    loop = 60.0 * int(bars[-1][0]) + int(bars[-1][1]) if bars else float("nan")
    lines = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    ours, ids = np.full((len(lines), 3), np.nan), set()
    for k, entry in enumerate(lines):
        ids.update(t["id"] for t in entry["tracks"])
        confirmed = [t for t in entry["tracks"] if t["status"] == "confirmed"]
        if confirmed:
            ours[k] = confirmed[0]["position"]
    return {"wall_s": wall, "loop_s": loop, "frames": len(lines), "positions": ours,
            "ids": len(ids)}


def _stats(estimate, reference) -> tuple:
    """(median top-view distance to the reference, median frame-to-frame step), metres."""
    seen = np.isfinite(estimate[:, 0])
    d = np.linalg.norm(estimate[seen][:, TOP] - reference[seen][:, TOP], axis=1)
    steps = np.linalg.norm(np.diff(estimate[:, TOP], axis=0), axis=1)
    steps = steps[np.isfinite(steps)]
    return (float(np.median(d)) if len(d) else float("nan"),
            float(np.median(steps)) if len(steps) else float("nan"))


def _cpu() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default=str(ROOT / "out" / "pf_peer"))
    p.add_argument("--frames", type=int, default=None, help="the first N frames (default all)")
    p.add_argument("--json", default=str(PEER_JSON),
                   help="the timings for `nlos-cl bench` ('' for none; default %(default)s)")
    args = p.parse_args()
    if not WALK.is_dir() or not (PEERS / "consumer-nlos" / "tracking.py").is_file():
        print(f"SKIP pf_peer: {WALK} or {PEERS / 'consumer-nlos'} is absent")
        return 0
    files = _frames(args.frames)
    shipped = np.array([np.load(f)["particles"].mean(axis=0) for f in files])
    with tempfile.TemporaryDirectory() as tmp:
        peer = run_peer(Path(tmp), files)
        ours = run_nlos_cl(Path(tmp), files)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "pf_estimates.json").write_text(json.dumps(
        {"frames": [f.name for f in files], "particle_means": peer["means"].tolist(),
         "shipped_particle_means": shipped.tolist(), "wall_s": peer["wall_s"],
         "loop_s": peer["loop_s"]}))
    rows = [("authors' PF (this run)", peer["frames"], peer["wall_s"], peer["loop_s"], "-",
             *_stats(peer["means"], shipped)),
            ("authors' PF (shipped)", len(files), float("nan"), float("nan"), "-",
             *_stats(shipped, shipped)),
            ("nlos-cl track", ours["frames"], ours["wall_s"], ours["loop_s"], ours["ids"],
             *_stats(ours["positions"], shipped))]
    print(f"{'tracker':24} {'frames':>6} {'wall s':>8} {'fps':>6} {'loop fps':>8} {'ids':>4} "
          f"{'to shipped PF m':>15} {'jitter m':>9}")
    for name, n, wall, loop, ids, dist, jit in rows:
        print(f"{name:24} {n:6d} {wall:8.1f} {n / wall:6.1f} {n / loop:8.1f} {ids!s:>4} "
              f"{dist:15.3f} {jit:9.4f}")
    wall_ratio = peer["wall_s"] / ours["wall_s"]  # the same frames: a time ratio is a fps one
    loop_ratio = peer["loop_s"] / ours["loop_s"]
    print(f"frames/s ratio nlos-cl track / authors' PF (wall, whole program): {wall_ratio:.2f}; "
          f"frame loops alone: {loop_ratio:.2f}")
    print(f"wrote {out / 'pf_estimates.json'}")
    if args.json:
        Path(args.json).write_text(json.dumps({
            "what": "scripts/pf_peer.sh: the consumer-nlos authors' particle filter and "
                    "nlos-cl track on the same walk frames, one after the other in one run",
            "date": time.strftime("%Y-%m-%d"), "cpu": _cpu(), "threads": os.cpu_count(),
            "frames": len(files), "ratio_wall": wall_ratio, "ratio_loop": loop_ratio,
            "rows": [{"tracker": name, "frames": n, "wall_s": wall, "loop_s": loop,
                      "ids": ids, "to_shipped_pf_m": dist, "jitter_m": jit}
                     for name, n, wall, loop, ids, dist, jit in rows[:1] + rows[2:]]},
            indent=1, default=lambda v: None))
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
