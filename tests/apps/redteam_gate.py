"""The red team's inputs for the HDF5 side of the input gate, bounded messages and noise in
`reproduce real` (issue 59 items 1, 3, 5): captures whose compressed chunk inflates past its
size, whose H declares 10^9 rows, with links or external storage below the root; sequences
declaring 10^9 frames or 10^8 targets a frame; YAML files holding 100 kB values where an error
would echo them; `reproduce real` on a noise-only dataset. redteam_cases.py adds GATE_CASES
to its CASES (it imports this module at its end, so import redteam_cases first)."""
from __future__ import annotations

import re
import sys
import zlib
from pathlib import Path

import h5py
import numpy as np
from redteam_cases import (
    LOC,
    MEM,
    SEC,
    SWEEP0,
    VAGUE,
    WRONG,
    Case,
    edited_capture,
    study,
)

LONG = "v" * 100_000  # a 100 kB value


def inflating_chunk(box, inflated=3 << 30):
    """H (as the capture's shape) stored as one deflate chunk whose stream holds `inflated`
    bytes of zeros (~3 MB stored): HDF5 inflates a chunk to its stream's end."""
    def edit(f):
        shape = f["H"].shape
        del f["H"]
        d = f.create_dataset("H", shape, np.float32, chunks=shape, compression="gzip")
        engine, block, parts = zlib.compressobj(9), bytes(64 << 20), []
        for _ in range(inflated // len(block)):
            parts.append(engine.compress(block))
        d.id.write_direct_chunk((0, 0), b"".join(parts) + engine.flush(), filter_mask=0)
    return edited_capture(box, edit, "bomb.h5")


def declaring_h(box, rows=10 ** 9):
    """H declared (rows, 3) float32, chunks never written: a 20 kB file declaring 12 GB."""
    def edit(f):
        del f["H"]
        f.create_dataset("H", (rows, f["sensor_grid_xyz"].shape[0]), np.float32,
                         chunks=(1024, f["sensor_grid_xyz"].shape[0]))
    return edited_capture(box, edit, "lying.h5")


def group_link(box):
    """An external link to a file outside, inside a group below the root."""
    with h5py.File(box.outside / "other.h5", "w") as o:
        o["H"] = np.zeros((6005, 3), np.float32)
    return edited_capture(box, lambda f: f.create_group("more").__setitem__(
        "H", h5py.ExternalLink(str(box.outside / "other.h5"), "H")), "group.h5")


def many_targets(box, targets=10 ** 8):
    """A sequence whose frame_truths declare `targets` targets a frame (2.4 GB a frame)."""
    path = box.copy("seq.h5", "targets.h5")
    with h5py.File(path, "a") as f:
        n = f["H"].shape[0]
        if "frame_truths" in f:
            del f["frame_truths"]
        f.create_dataset("frame_truths", (n, targets, 3), np.float64, chunks=(1, 1 << 16, 3))
    return path


def noise_dataset(box):
    """A noise-only CC-SOCR folder where `reproduce real` looks for figure 4's scan."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from test_reproduce_real import _ccsocr_dataset
    _ccsocr_dataset(box.work / "data", signal=False)
    return box.work / "data"


def not_detected(out, err):
    """reproduce real's index: the CC-SOCR case neither detected nor met."""
    return bool(re.search(r"ccsocr\s+6 points\s+\S+\s+False\s+False", out))


GATE_CASES = [
    Case(MEM, "a capture whose one deflate chunk inflates to 3 GiB (~3 MB stored)",
         lambda b: ["locate", inflating_chunk(b), *LOC]),
    Case(MEM, "a capture whose H declares 10^9 rows (a 20 kB file)",
         lambda b: ["locate", declaring_h(b), *LOC]),
    Case(SEC, "a capture with an external link to a file outside, in a group",
         lambda b: ["locate", group_link(b), *LOC]),
    Case(MEM, "a sequence declaring 10^9 frames (H only)",
         lambda b: ["track", _billion_h(b), "--no-progress"]),
    Case(MEM, "a sequence whose frame_truths declare 10^8 targets a frame",
         lambda b: ["track", many_targets(b), "--no-progress"]),
    Case(VAGUE, "a study whose 100 kB key appears twice",
         lambda b: ["sweep", study(b, f"? {LONG}\n: 1\n? {LONG}\n: 2\n"), "--out",
                    b.work / "o", *SWEEP0]),
    Case(VAGUE, "a study with a YAML error on a 100 kB line",
         lambda b: ["sweep", study(b, f"axes: [1, 2\nnotes: {LONG}\n"), "--out", b.work / "o",
                    *SWEEP0]),
    Case(VAGUE, "a study whose seeds are a 100 kB string",
         lambda b: ["sweep", study(b, f"seeds: {LONG}\naxes: [{{path: noise.snr_db, values: "
                                   "[10]}]\n"), "--out", b.work / "o", *SWEEP0]),
    Case(VAGUE, "a scene file whose occlusion is a 100 kB string",
         lambda b: ["simulate", b.text("scene.yaml", "setup: {laser_spot: [0, 0, 0], "
                                       "detector_spots: [[-0.5, 0, 0]]}\ntargets: [{shape: "
                                       "rectangle, size_m: [0.3, 1.6], position: [4, 2, 0]}]\n"
                                       f"occlusion: {LONG}\n"), "--out", "o.h5"]),
    Case(WRONG, "reproduce real on a noise-only CC-SOCR dataset",
         lambda b: ["reproduce", "real", "--quick", "--data", noise_dataset(b), "--out",
                    b.work / "r"], ok=not_detected),
]


def _billion_h(box):
    path = box.copy("seq.h5", "frames.h5")
    with h5py.File(path, "a") as f:
        f["H"].resize(10 ** 9, axis=0)  # chunks never written: the file stays small
    return path
