"""The hostile inputs tests/apps/redteam.py tries: one or more per bullet of issue 24 (data loss,
security, hangs, unbounded memory, silently wrong, tracebacks, vague). Each case builds its
inputs inside its own sandbox (`Box`: `work/`, the user's folder and the command's cwd, and
`outside/`, files the command must never read or change) and returns the `nlos-cl` arguments.

`ok` judges an exit status of 0: the right answer, or the warning that was due. A case whose
input must be refused leaves it None (exit 0 is then "silently wrong").
"""
from __future__ import annotations

import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import h5py
import numpy as np

GiB = 1 << 30
SECRET = "REDTEAM-SECRET-4f1c"  # in outside/secret.txt: seen in any output means it was read

PAPER = """setup: {laser_spot: [0, 0, 0], detector_spots: [[-0.5, 0, 0], [-1, 0, 0], [-1.5, 0, 0]]}
targets: [{shape: rectangle, size_m: [0.3, 1.6], normal: [-1, 0, 0], position: [4, 2, 0]}]
facet_size_m: 0.05
time_axis: {dt_s: 10e-12}
"""
STUDY = """scene:
  setup: {detector_spots: [[-0.5, 0, 0], [-1, 0, 0], [-1.5, 0, 0]]}
  targets: [{shape: rectangle, size_m: [0.3, 1.6], normal: [-1, 0, 0], position: [4, 2, 0]}]
  facet_size_m: 0.05
  time_axis: {dt_s: 1.0e-11}
"""


@dataclass
class Box:
    work: Path
    outside: Path
    fixtures: object  # redteam.Fixtures: .path(name) builds a fixture on first use
    cleanup: list = field(default_factory=list)  # commands the runner runs after the case

    def copy(self, name: str, as_name: str | None = None) -> Path:
        return Path(shutil.copy(self.fixtures.path(name), self.work / (as_name or name)))

    def text(self, name: str, text: str, encoding: str = "utf-8") -> Path:
        path = self.work / name
        path.write_text(text, encoding)
        return path


@dataclass
class Case:
    cls: str                               # the bullet
    name: str                              # what the input is, for the table
    make: Callable[[Box], list]            # builds the inputs, returns nlos-cl's arguments
    ok: Callable[[str, str], bool] | None = None  # (stdout, stderr) of an exit 0: right?
    limit_as: int = 4 * GiB                # address-space limit of the run
    lock: str | None = None                # a work/ file the red team holds open for writing
    answer_codes: tuple = (0,)             # exit statuses that carry an answer `ok` judges


def located_within(metres: float):
    """exit 0 is right if the printed error (`error 0.0233 m`) is below `metres`."""
    def ok(out, err):
        found = [float(x) for x in re.findall(r"error ([0-9.e+-]+) m", out)]
        return bool(found) and max(found) < metres
    return ok


def says(*words):
    """exit 0 is right if the output (stdout or a warning) says one of these words."""
    return lambda out, err: any(w.lower() in (out + err).lower() for w in words)


def edited_capture(box: Box, edit, name="cap.h5") -> Path:
    path = box.copy("cap.h5", name)
    with h5py.File(path, "a") as f:
        edit(f)
    return path


def set_field(name, value):
    def edit(f):
        del f[name]
        f[name] = value
    return edit


def noise_capture(box: Box) -> Path:
    def edit(f):
        h = f["H"][()]
        scale = float(np.abs(h).max()) / 3
        f["H"][...] = np.random.default_rng(1).normal(0, scale, h.shape).astype(h.dtype)
    return edited_capture(box, edit, "noise.h5")


def alias_bomb(levels=9, width=9) -> str:
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x]"]
    for i in range(1, levels):
        lines.append(f"a{i}: &a{i} [{', '.join(['*a%d' % (i - 1)] * width)}]")
    return "\n".join(lines)


def study(box, body, name="study.yaml"):
    return box.text(name, STUDY + body)


def runner_study(box, runner, values):
    return box.text("study.yaml", f"runner: {runner!r}\naxes:\n  - name: cmd\n"
                    f"    values: {values!r}\n")


def scene(box, text, name="scene.yaml"):
    return box.text(name, text)


def done_study(box) -> Path:
    """A results folder as a finished one-run study left it (the fixture)."""
    shutil.copytree(box.fixtures.path("study_out"), box.work / "out")
    return box.work / "out"


def _bomb_scene(box):
    return scene(box, alias_bomb() + "\n" + PAPER.replace("setup:", "description: *a8\nsetup:"))


def _fifo(box, name="F.h5"):
    import os
    os.mkfifo(box.work / name)
    return box.work / name


def _external_h(box, target: Path, name="ext.h5"):
    def edit(f):
        shape, dtype = f["H"].shape, f["H"].dtype
        del f["H"]
        f.create_dataset("H", shape, dtype, external=[(str(target), 0, h5py.h5f.UNLIMITED)])
    return edited_capture(box, edit, name)


def _linked_h(box, kind):
    def edit(f):
        del f["H"]
        if kind == "external":
            f["H"] = h5py.ExternalLink(str(box.outside / "other.h5"), "H")
        else:
            f["H"] = h5py.SoftLink("/sensor_xyz")
    with h5py.File(box.outside / "other.h5", "w") as o:
        o["H"] = np.zeros((6005, 3), np.float32)
    return edited_capture(box, edit, f"{kind}.h5")


def _declared_frames(box, n):
    def edit(f):
        data = f["H"][()]
        del f["H"]
        f.create_dataset("H", (n,) + data.shape, data.dtype, chunks=(1,) + data.shape)
        f["H"][:20] = data
        f["frame_t_s"] = np.arange(20) / 10.0
    return edited_capture(box, edit, "decl.h5")


def _unused_dataset(box):
    def edit(f):
        f.create_dataset("unused", (3 * GiB // 4,), np.float32, chunks=(1 << 20,))
    return edited_capture(box, edit, "unused.h5")


def _many_strings(box):
    def edit(f):
        f.create_dataset("scene_info_extra", (10 ** 8,), "S8", chunks=(1 << 20,))
    return edited_capture(box, edit, "strings.h5")


def _userblock(box):
    src = box.fixtures.path("cap.h5")
    path = box.work / "ub.h5"
    with h5py.File(src, "r") as a, h5py.File(path, "w", userblock_size=512) as b:
        for key in a:
            a.copy(a[key], b, name=key)
    return path


def _truncated(box):
    path = box.copy("cap.h5", "trunc.h5")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    return path


def _mat73(box):
    path = box.work / "rect.mat"
    with h5py.File(path, "w", userblock_size=512) as f:
        f["rect_data"] = np.zeros((8, 8, 64), np.float64)
        f["width"] = np.array([[0.35]])
        for name in ("rect_data", "width"):
            f[name].attrs["MATLAB_class"] = np.bytes_("double")
    with open(path, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 "
                 b"HDF5 schema 1.00 .")
    return path


def _tiny_disk(box) -> Path:
    """A 64 KiB tmpfs at work/disk (a full disk for a noisy capture); unmounted by the runner."""
    import subprocess
    disk = box.work / "disk"
    disk.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(disk)], check=True,
                   capture_output=True, timeout=10)
    box.cleanup.append(["umount", str(disk)])
    return disk


def _two_laser_background(box):
    return ["locate", box.copy("paired.h5"), "--background", box.copy("cap.h5", "bg.h5"),
            "--estimator", "paper"]


def _user_capture(box):
    path = box.work / "measured.h5"
    with h5py.File(path, "w") as f:  # a y-tal capture nlos_cl did not write
        f["H"] = np.ones((100, 3), np.float32)
        f["delta_t"] = np.float32(3e-3)
        f["scene_info"] = "captured in the lab, 2024"
    return path


def _corrupt_study_json(box):
    out = done_study(box)
    (out / "study.json").write_text("{not json")
    return ["sweep", study(box, "axes: [{path: noise.snr_db, values: [10]}]\n"), "--out", out,
            "--resume", "--workers", "0", "--no-progress"]


def _stray_part(box):
    out = done_study(box)
    (out / "runs.parquet" / "stray.txt").write_text("hello")
    return ["sweep", study(box, "axes: [{path: noise.snr_db, values: [10]}]\n"), "--out", out,
            "--resume", "--workers", "0", "--no-progress"]


def _study_json_gone(box):
    out = done_study(box)
    (out / "study.json").unlink()
    return ["sweep", study(box, "axes: [{path: noise.snr_db, values: [0, 20]}]\n"), "--out", out,
            "--resume", "--workers", "0", "--no-progress"]


def _rmtree_study(box):
    (box.work / "thesis").mkdir()
    (box.work / "thesis" / "chapter1.tex").write_text("my chapter")
    return ["sweep", runner_study(box, "shutil:rmtree", [str(box.work / "thesis")]), "--out",
            box.work / "o", "--workers", "0", "--no-progress"]


def _silent_server(box):
    """A TCP port that accepts and never answers (not a Dask scheduler)."""
    import socket
    import threading
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    threading.Thread(target=lambda: [srv.accept() for _ in range(8)], daemon=True).start()
    return f"tcp://127.0.0.1:{srv.getsockname()[1]}"


SWEEP0 = ["--workers", "0", "--no-progress"]
DL, SEC, HANG, MEM, WRONG, TB, VAGUE = ("data loss", "security", "hangs", "unbounded memory",
                                        "silently wrong", "tracebacks", "vague")
LOC = ["--estimator", "paper"]


def _existing(box, name, content="my own file\n"):
    path = box.work / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(content)
    return path


CASES = [
    # ---- data loss: an output over what the user made
    Case(DL, "demo --png over the user's thesis.pdf",
         lambda b: ["demo", "--png", _existing(b, "thesis.pdf"), "--estimator", "paper"]),
    Case(DL, "reproduce fig5 --doc over the user's notes.md",
         lambda b: ["reproduce", "fig5", "--quick", "--seeds", "1", "--out", b.work / "r",
                    "--doc", _existing(b, "notes.md")]),
    Case(DL, "reproduce fig5 --out over the user's fig5.csv",
         lambda b: ["reproduce", "fig5", "--quick", "--seeds", "1", "--out",
                    _existing(b, "r/fig5.csv").parent]),
    Case(DL, "bench --out over the user's performance.md",
         lambda b: ["bench", "--smoke", "--out", _existing(b, "p/performance.md").parent]),
    Case(DL, "locate --map over the user's own .npz",
         lambda b: ["locate", b.copy("cap.h5"), *LOC, "--map", b.copy("mine.npz")]),
    Case(DL, "sweep --out into a folder with the user's summary.csv",
         lambda b: ["sweep", study(b, "axes: [{path: noise.snr_db, values: [10]}]\n"), "--out",
                    _existing(b, "s/summary.csv").parent, *SWEEP0]),
    Case(DL, "simulate --out over a measured capture nlos_cl did not write",
         lambda b: ["simulate", "--out", _user_capture(b), "--facet", "0.05"]),
    Case(DL, "simulate --out onto a folder, --force",
         lambda b: ["simulate", "--out", _existing(b, "d.h5/keep.txt").parent, "--force",
                    "--facet", "0.05"]),
    Case(DL, "simulate --out /dev/null (a character device), --force",
         lambda b: ["simulate", "--out", "/dev/null", "--force", "--facet", "0.05"]),
    Case(DL, "track --video over the user's existing movie.gif",
         lambda b: ["track", b.copy("seq.h5"), "--video", _existing(b, "movie.gif"),
                    "--no-progress"]),
    Case(DL, "convert --out over the user's file",
         lambda b: ["convert", _mat73(b), "--format", "lct", "--out", _existing(b, "mine.h5")]),
    Case(DL, "full disk during simulate (a 64 KiB tmpfs; needs root)",
         lambda b: ["simulate", "--out", _tiny_disk(b) / "full.h5", "--snr-db", "10",
                    "--facet", "0.05"]),
    # ---- security: code run, files outside read or changed
    Case(SEC, "study runner os:system with an axis of commands",
         lambda b: ["sweep", runner_study(b, "os:system", [f"touch {b.outside}/owned"]),
                    "--out", b.work / "o", *SWEEP0]),
    Case(SEC, "study runner subprocess:getoutput",
         lambda b: ["sweep", runner_study(b, "subprocess:getoutput",
                                          [f"cat {b.outside}/secret.txt"]),
                    "--out", b.work / "o", *SWEEP0]),
    Case(SEC, "study runner shutil:rmtree on a user folder", _rmtree_study),
    Case(SEC, "study runner builtins:exec",
         lambda b: ["sweep", runner_study(b, "builtins:exec",
                                          [f"open('{b.outside}/owned', 'w')"]),
                    "--out", b.work / "o", *SWEEP0]),
    Case(SEC, "simulate --out link.h5 (a symlink to a file outside), --force",
         lambda b: ["simulate", "--out", _symlink(b, "link.h5", b.outside / "thesis.h5"),
                    "--force", "--facet", "0.05"]),
    Case(SEC, "capture whose H is external raw storage on a file outside",
         lambda b: ["locate", _external_h(b, b.outside / "secret.txt"), *LOC]),
    Case(SEC, "capture whose H is an external link to a file outside",
         lambda b: ["locate", _linked_h(b, "external"), *LOC]),
    Case(SEC, "capture whose H is a soft link",
         lambda b: ["locate", _linked_h(b, "soft"), *LOC]),
    Case(SEC, "scene file with a !!python/object/apply tag",
         lambda b: ["simulate", scene(b, PAPER + f"description: !!python/object/apply:os.system "
                                      f"['touch {b.outside}/owned']\n"),
                    "--out", b.work / "o.h5"]),
    Case(SEC, "study file with a !!python/name tag",
         lambda b: ["sweep", study(b, "axes: [{path: noise.snr_db, values: "
                                   "[!!python/name:os.system ]}]\n"), "--out", b.work / "o",
                    *SWEEP0]),
    Case(SEC, "capture on a FIFO (must not hang)", lambda b: ["locate", _fifo(b), *LOC]),
    # ---- hangs
    Case(HANG, "YAML alias bomb (9 x 9) in a scene's description",
         lambda b: ["simulate", _bomb_scene(b), "--out", b.work / "o.h5"]),
    Case(HANG, "YAML alias bomb in a target's position",
         lambda b: ["simulate", scene(b, alias_bomb() + "\n" + PAPER.replace(
             "position: [4, 2, 0]", "position: *a8")), "--out", b.work / "o.h5"]),
    Case(HANG, "5,000 small spheres",
         lambda b: ["simulate", scene(b, PAPER.replace("targets: [", "targets: [" + "".join(
             f"{{shape: sphere, radius_m: 0.01, position: [{2 + i % 50 * 0.05:.2f}, "
             f"{1 + i // 50 * 0.03:.2f}, 0]}}, " for i in range(5000)))),
                    "--out", b.work / "o.h5"]),
    Case(HANG, "locate --targets 50 on a 3-detector capture",
         lambda b: ["locate", b.copy("cap.h5"), "--targets", "50"]),
    Case(HANG, "locate --targets 100000",
         lambda b: ["locate", b.copy("cap.h5"), "--targets", "100000"]),
    Case(HANG, "track --targets 1000",
         lambda b: ["track", b.copy("seq.h5"), "--targets", "1000", "--no-progress"]),
    Case(HANG, "a sequence declaring 10^7 frames of which 20 are written",
         lambda b: ["track", _declared_frames(b, 10 ** 7), "--no-progress"]),
    Case(HANG, "YAML alias bomb in a study file",
         lambda b: ["sweep", study(b, alias_bomb() + "\naxes: [{path: noise.snr_db, values: "
                                   "*a8}]\n"), "--out", b.work / "o", *SWEEP0]),
    Case(HANG, "sweep --scheduler at a server that is not Dask",
         lambda b: ["sweep", study(b, "axes: [{path: noise.snr_db, values: [10]}]\n"),
                    "--out", b.work / "o", "--scheduler", _silent_server(b), "--no-progress"]),
    Case(HANG, "model estimator on a 256-detector SPAD patch", lambda b: ["locate", b.copy(
        "patch.h5")], ok=located_within(0.1)),
    # ---- unbounded memory
    Case(MEM, "a 1 fs pulse on the paper's scene",
         lambda b: ["simulate", scene(b, PAPER.replace("setup: {", "setup: {pulse: {fwhm_s: "
                                                       "1e-15}, ")), "--out", b.work / "o.h5"],
         ok=says("wrote")),
    Case(MEM, "a 1 ms pulse",
         lambda b: ["simulate", scene(b, PAPER.replace("setup: {", "setup: {pulse: {fwhm_s: "
                                                       "1e-3}, ")), "--out", b.work / "o.h5"]),
    Case(MEM, "0.4 x 0.4 x 1.6 m box, 2 mm facets, 2 fs pulse",
         lambda b: ["simulate", scene(b, PAPER.replace("setup: {", "setup: {pulse: {fwhm_s: "
                                                       "2e-15}, ").replace(
             "shape: rectangle, size_m: [0.3, 1.6], normal: [-1, 0, 0]",
             "shape: box, size_m: [0.4, 0.4, 1.6]").replace("0.05", "0.002")),
                    "--out", b.work / "o.h5"]),
    Case(MEM, "a line generator of 10^9 detector spots",
         lambda b: ["simulate", scene(b, PAPER.replace(
             "detector_spots: [[-0.5, 0, 0], [-1, 0, 0], [-1.5, 0, 0]]",
             "detector_spots: {line: {start: [-0.5, 0, 0], stop: [-1.5, 0, 0], count: "
             "1000000000}}")), "--out", b.work / "o.h5"]),
    Case(MEM, "a sequence declaring 10^9 frames",
         lambda b: ["track", _declared_frames(b, 10 ** 9), "--no-progress"]),
    Case(MEM, "simulate --frames 100000000",
         lambda b: ["simulate", b.copy("walk.yaml"), "--frames", "100000000", "--out",
                    b.work / "o.h5"]),
    Case(MEM, "a study of 10^9 runs",
         lambda b: ["sweep", study(b, "axes: [{path: noise.snr_db, range: {start: 0, stop: 1, "
                                   "num: 1000000000}}]\n"), "--out", b.work / "o", *SWEEP0]),
    Case(MEM, "a study of 10^9 seeds",
         lambda b: ["sweep", study(b, "seeds: 1000000000\n"), "--out", b.work / "o", *SWEEP0]),
    Case(MEM, "an unused 3 GiB dataset in a capture",
         lambda b: ["locate", _unused_dataset(b), *LOC], ok=located_within(0.05)),
    Case(MEM, "10^8 strings beside scene_info in a capture",
         lambda b: ["locate", _many_strings(b), *LOC], ok=located_within(0.05)),
    Case(MEM, "locate --map on a huge region",
         lambda b: ["locate", b.copy("cap.h5"), *LOC, "--region", "-50", "50", "0", "50",
                    "-50", "50", "--step", "0.001", "--map", b.work / "m.npz"]),
    Case(MEM, "track --video on a huge region",
         lambda b: ["track", b.copy("seq.h5"), "--region", "-50", "50", "-50", "50", "0.01", "50",
                    "--step", "0.001", "--video", b.work / "v.gif", "--no-progress"]),
    # ---- silently wrong
    Case(WRONG, "pure noise, no target (paper's argmax)",
         lambda b: ["locate", noise_capture(b), *LOC], ok=says("no target"), answer_codes=(0, 3)),
    Case(WRONG, "pure noise, no target (model estimator)",
         lambda b: ["locate", noise_capture(b)], ok=says("no target"), answer_codes=(0, 3)),
    Case(WRONG, "t_accounts_first_and_last_bounces stored as the text 'False'",
         lambda b: ["locate", edited_capture(b, set_field("t_accounts_first_and_last_bounces",
                                                          "False")), *LOC],
         ok=located_within(0.05)),
    Case(WRONG, "frame_t_s in milliseconds",
         lambda b: ["track", _scaled_times(b, 1000.0), "--no-progress"],
         ok=says("millisecond", " ms", "unit")),
    Case(WRONG, "a paired capture minus a 1-laser background", _two_laser_background),
    Case(WRONG, "device_distance_m: 1e39 in a scene",
         lambda b: ["simulate", scene(b, PAPER.replace("setup: {", "setup: {device_distance_m: "
                                                       "1e39, ")), "--out", b.work / "o.h5"]),
    Case(WRONG, "duplicate YAML keys (targets twice)",
         lambda b: ["simulate", scene(b, PAPER + "targets: [{shape: sphere, radius_m: 0.2, "
                                      "position: [2, 2, 0]}]\n"), "--out", b.work / "o.h5"]),
    Case(WRONG, "spad_patch counts [2.7, 2.7]",
         lambda b: ["simulate", scene(b, _patch("[2.7, 2.7]")), "--out", b.work / "o.h5"]),
    Case(WRONG, "--resume on a folder whose study.json is gone", _study_json_gone),
    Case(WRONG, "a capture with wall spots in millimetres",
         lambda b: ["locate", edited_capture(b, _times("sensor_grid_xyz", 1000.0)), *LOC]),
    # ---- tracebacks
    Case(TB, "20,000 nested brackets in a scene file",
         lambda b: ["simulate", scene(b, "description: " + "[" * 20000 + "]" * 20000 + "\n"
                                      + PAPER), "--out", b.work / "o.h5"]),
    Case(TB, "spad_patch counts [a, b]",
         lambda b: ["simulate", scene(b, _patch("[a, b]")), "--out", b.work / "o.h5"]),
    Case(TB, "photon noise n_pulses 1e30",
         lambda b: ["simulate", scene(b, PAPER + "noise: {photons: {n_pulses: 1e30}}\n"),
                    "--out", b.work / "o.h5"]),
    Case(TB, "simulate --snr-db -1e300",
         lambda b: ["simulate", "--out", b.work / "o.h5", "--snr-db", "-1e300", "--facet",
                    "0.05"]),
    Case(TB, "simulate --fps 1e-300 then track",
         lambda b: ["simulate", b.copy("walk.yaml"), "--frames", "3", "--fps", "1e-300",
                    "--out", b.work / "o.h5"]),
    Case(TB, "track --accel 1e300",
         lambda b: ["track", b.copy("seq.h5"), "--accel", "1e300", "--no-progress"]),
    Case(TB, "sequence frame_truths of the wrong shape",
         lambda b: ["track", _seq_edit(b, set_field("frame_truths", np.zeros((2, 7)))),
                    "--no-progress"]),
    Case(TB, "study range stop: .inf",
         lambda b: ["sweep", study(b, "axes: [{path: noise.snr_db, range: {start: 0, stop: "
                                   ".inf, step: 1}}]\n"), "--out", b.work / "o", *SWEEP0]),
    Case(TB, "study range with text values",
         lambda b: ["sweep", study(b, "axes: [{path: noise.snr_db, range: {start: a, stop: b, "
                                   "step: c}}]\n"), "--out", b.work / "o", *SWEEP0]),
    Case(TB, "study axis named error_m (a result column)",
         lambda b: ["sweep", study(b, "axes: [{path: noise.snr_db, name: error_m, values: "
                                   "[10]}]\n"), "--out", b.work / "o", *SWEEP0]),
    Case(TB, "--resume with a corrupt study.json", _corrupt_study_json),
    Case(TB, "--resume with a stray file in runs.parquet/", _stray_part),
    Case(TB, "--scheduler naming a YAML file",
         lambda b: ["sweep", study(b, "axes: [{path: noise.snr_db, values: [10]}]\n"), "--out",
                    b.work / "o", "--scheduler", study(b, "", "sched.yaml"), "--no-progress"]),
    Case(TB, "HOME is a file (no cache folder can be made)",
         lambda b: ["locate", b.copy("cap.h5"), *LOC], ok=located_within(0.05)),
    Case(TB, "locate under a 600 MB address-space limit",
         lambda b: ["locate", b.copy("cap.h5"), *LOC], limit_as=600_000 * 1024),
    Case(TB, "a 0.2 fs pulse under 4 GB",
         lambda b: ["simulate", scene(b, PAPER.replace("setup: {", "setup: {pulse: {fwhm_s: "
                                                       "2e-16}, ")), "--out", b.work / "o.h5"],
         ok=says("wrote")),
    # ---- vague: a corrupted or odd file must say what is wrong and how to fix it
    Case(VAGUE, "a truncated capture", lambda b: ["locate", _truncated(b), *LOC]),
    Case(VAGUE, "H of the wrong size",
         lambda b: ["locate", edited_capture(b, set_field("H", np.ones((7, 5), "f4"))), *LOC]),
    Case(VAGUE, "a group where H should be",
         lambda b: ["locate", edited_capture(b, _group("H")), *LOC]),
    Case(VAGUE, "sensor_grid_xyz missing",
         lambda b: ["locate", edited_capture(b, lambda f: f.__delitem__("sensor_grid_xyz")),
                    *LOC]),
    Case(VAGUE, "a text file named F.h5", lambda b: ["locate", b.text("F.h5", "hello"), *LOC]),
    Case(VAGUE, "a folder named F.h5",
         lambda b: ["locate", _existing(b, "F.h5/x").parent, *LOC]),
    Case(VAGUE, "a capture another program holds open for writing",
         lambda b: ["locate", b.copy("cap.h5", "locked.h5"), *LOC], lock="locked.h5",
         ok=located_within(0.05)),
    Case(VAGUE, "a valid capture with a 512-byte HDF5 user block",
         lambda b: ["locate", _userblock(b), *LOC], ok=located_within(0.05)),
    Case(VAGUE, "a MATLAB v7.3 .mat as an LCT dataset",
         lambda b: ["convert", _mat73(b), "--format", "lct", "--out", b.work / "o.h5"],
         ok=lambda out, err: "wrote" in out or "o.h5" in out),
    Case(VAGUE, "a UTF-16 scene file",
         lambda b: ["simulate", b.text("s16.yaml", PAPER, "utf-16"), "--out", b.work / "o.h5"],
         ok=lambda out, err: "wrote" in out),
    Case(VAGUE, "a study with a bad field value",
         lambda b: ["sweep", study(b, "axes: [{path: 'targets[0].size_m[0]', values: [-1]}]\n"),
                    "--out", b.work / "o", *SWEEP0]),
    Case(VAGUE, "calibrate with a CSV of text",
         lambda b: ["calibrate", b.text("pairs.csv", "path,time\na,b\n")]),
    Case(VAGUE, "a scene file that is a YAML list",
         lambda b: ["simulate", b.text("l.yaml", "- 1\n- 2\n"), "--out", b.work / "o.h5"]),
    Case(VAGUE, "a binary file as a scene",
         lambda b: ["simulate", b.copy("cap.h5", "bin.yaml"), "--out", b.work / "o.h5"]),
]


def _symlink(box, name, target: Path):
    (box.work / name).symlink_to(target)
    return box.work / name


def _patch(counts):
    return PAPER.replace("detector_spots: [[-0.5, 0, 0], [-1, 0, 0], [-1.5, 0, 0]]",
                         f"detector_spots: {{spad_patch: {{centre: [-1, 0, 0], counts: {counts}, "
                         "pitch_m: 0.0375}}")


def _times(name, factor):
    def edit(f):
        value = f[name][()] * factor
        del f[name]
        f[name] = value
    return edit


def _group(name):
    def edit(f):
        del f[name]
        f.create_group(name)
    return edit


def _seq_edit(box, edit):
    path = box.copy("seq.h5")
    with h5py.File(path, "a") as f:
        edit(f)
    return path


def _scaled_times(box, factor):
    return _seq_edit(box, _times("frame_t_s", factor))


# ---- issue 59: the readers, by class (builders in redteam_readers.py)
import redteam_readers as R  # beside this file: the runner puts its folder on sys.path

SIM = ["--out", "o.h5"]
CONVERT = ["--out", "o.h5"]
wrote = says("wrote")
CASES += [
    Case(MEM, "a bz2 STL bomb (600 MB of triangles in ~1 kB) as a scene's mesh",
         lambda b: ["simulate", R.mesh_scene(b, R.bz2_bomb(b)), *SIM]),
    Case(MEM, "a zip whose STL member declares 4 GiB",
         lambda b: ["simulate", R.mesh_scene(b, R.zip_declaring(b)), *SIM]),
    Case(MEM, "a sparse 3 GiB OBJ as a scene's mesh",
         lambda b: ["simulate", R.mesh_scene(b, R.sparse(b, "big.obj")), *SIM]),
    Case(MEM, "a glTF whose buffer is a sparse 3 GiB file",
         lambda b: ["simulate", R.mesh_scene(b, R.gltf(b, byte_length=3 << 30,
                                                       sparse_bytes=3 << 30)), *SIM]),
    Case(MEM, "a zlib-compressed .mat element declaring 3.9 GB",
         lambda b: ["convert", R.mat_declaring(b), "--format", "lct", *CONVERT]),
    Case(MEM, "an .npz whose raw 'hists' shadows the checked hists.npy",
         lambda b: ["convert", R.volumes(b, shadow=True), *CONVERT]),
    Case(MEM, "a sequence declaring 10^9 frames and 10^9 frame times",
         lambda b: ["track", R.billion_frames(b), "--no-progress"]),
    Case(HANG, "a glTF whose buffer is a FIFO",
         lambda b: ["simulate", R.mesh_scene(b, R.gltf(b, fifo=True)), *SIM]),
    Case(HANG, "an OBJ whose mtllib is a FIFO (read without its materials)",
         lambda b: ["simulate", R.mesh_scene(b, R.obj_with_fifo_mtl(b)), *SIM], ok=wrote),
    Case(HANG, "a scene's mesh file that is a FIFO",
         lambda b: ["simulate", R.mesh_scene(b, R.fifo(b, "m.stl")), *SIM]),
    Case(HANG, "a consumer-nlos frame that is a FIFO",
         lambda b: ["convert", R.volumes(b, fifo_frame=True), *CONVERT]),
    Case(TB, "a Keyhole scan with 0 frames",
         lambda b: ["convert", R.keyhole(b, np.zeros((0, 2000))), *CONVERT]),
    Case(TB, "a Keyhole scan whose data is a scalar",
         lambda b: ["convert", R.keyhole(b, np.float64(3.0)), *CONVERT]),
    Case(TB, "a compound (complex) rect_data in a v7.3 .mat",
         lambda b: ["convert", R.mat73(b.work / "c.mat", {"rect_data": np.zeros(
             (2, 3, 4), dtype=[("real", "<f8"), ("imag", "<f8")]), "width": np.array([[0.3]])}),
             "--format", "lct", *CONVERT]),
    Case(TB, "a sparse all-zero rect_data in a v7.3 .mat",
         lambda b: ["convert", R.mat73(b.work / "s.mat", {"rect_data": {"jc": np.zeros(
             65, np.uint64)}, "width": np.array([[0.3]])}), "--format", "lct", *CONVERT]),
    Case(TB, "a v5 .mat whose complex flag has no imaginary part (crashed scipy)",
         lambda b: ["convert", R.mat_flipped(b, 145, 0x08), "--format", "lct", *CONVERT]),
    Case(TB, "a v5 .mat whose data element has type code 8 (crashed scipy)",
         lambda b: ["convert", R.mat_flipped(b, 200, 0x01), "--format", "lct", *CONVERT]),
    Case(WRONG, "f-k tofgrid in nanoseconds",
         lambda b: ["convert", R.fk(b, tof_scale=1e-3), *CONVERT]),
    Case(WRONG, "f-k z_offset in millimetres",
         lambda b: ["convert", R.fk(b, z_offset=50.0), *CONVERT]),
    Case(WRONG, "a calibration CSV whose first row has a typo (taken for a header)",
         lambda b: ["calibrate", b.text("pairs.csv", "2.5,5.17e-8x\n3.0,1.0e-8\n3.5,1.17e-8\n"
                                        "4.0,1.33e-8\n")]),
    Case(WRONG, "an ASCII STL cut after its first facet",
         lambda b: ["simulate", R.mesh_scene(b, R.cut(b, "m.stl", R.exported("stl_ascii"),
                                                      R.exported("stl_ascii").index(
                                                          b"endfacet") + 9)), *SIM]),
    Case(WRONG, "a binary STL cut after its first triangle",
         lambda b: ["simulate", R.mesh_scene(b, R.cut(b, "m.stl", R.exported("stl"), 134)),
                    *SIM]),
    Case(WRONG, "an OBJ cut inside its last face",
         lambda b: ["simulate", R.mesh_scene(b, R.cut(b, "m.obj", R.exported("obj"), -3)),
                    *SIM]),
    Case(DL, "simulate --out over an nlos_cl capture whose H the user replaced",
         lambda b: ["simulate", "--out", R.ours_then_edited(b, "cap.h5", R.measured),
                    "--facet", "0.05"]),
    Case(DL, "convert --out over an nlos_cl capture the user added a dataset to",
         lambda b: ["convert", _mat73(b), "--format", "lct", "--out",
                    R.ours_then_edited(b, "cap.h5", R.added)]),
    Case(DL, "simulate --frames --out over an nlos_cl sequence the user edited",
         lambda b: ["simulate", b.copy("walk.yaml"), "--frames", "2", "--out",
                    R.ours_then_edited(b, "seq.h5", R.measured)]),
]

# ---- issue 59: studies and sweeps, by class (cases in redteam_studies.py)
from redteam_studies import STUDY_CASES  # beside this file; it imports the names above

CASES += STUDY_CASES

# ---- issue 59: the HDF5 gate, bounded messages, noise in reproduce real (redteam_gate.py)
from redteam_gate import GATE_CASES  # beside this file; it imports the names above

CASES += GATE_CASES

# ---- issue 59: the same classes by other routes (containers, commands, fields, the API)
from redteam_routes import ROUTE_CASES  # beside this file; it imports the names above

CASES += ROUTE_CASES
