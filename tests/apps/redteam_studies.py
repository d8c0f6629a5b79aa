"""The red team's study and sweep inputs (issue 59, the hostile classes of the sweep report):
runners that reach nlos_cl's own functions, system files named as the scene, two sweeps on one
folder, axes that overwrite each other or repeat, grids the search cannot score, deep and
bloated study files. Each builds its study (and any inner study, module or folder) in the
case's sandbox and runs `nlos-cl sweep`. redteam_cases.py adds STUDY_CASES to its CASES (it
imports this module at its end, so import redteam_cases first).

Not here: class 25 (a 100,000-deep study given to nl.sweep from Python) is a library call with
no command line; tests/sweep/test_sweep_bounds.py covers it."""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from redteam_cases import (
    DL,
    MEM,
    SEC,
    SECRET,
    SWEEP0,
    TB,
    VAGUE,
    WRONG,
    Case,
    done_study,
    says,
    study,
)

REPO = Path(__file__).resolve().parents[2]
LONG = 100_000  # characters of a bloated value
SNR = "axes: [{path: noise.snr_db, values: [10]}]\n"


def sweep(box, text, *extra, name="s.yaml"):
    """`nlos-cl sweep` of a study written as `text` (no base scene), out to work/o."""
    return ["sweep", box.text(name, text), "--out", box.work / "o", *SWEEP0, *extra]


def based(box, body, *extra):
    """`nlos-cl sweep` of the red team's paper scene plus `body`."""
    return ["sweep", study(box, body), "--out", box.work / "o", *SWEEP0, *extra]


def inner(box):
    """A shell study the hostile runners try to start: it would leave outside/owned."""
    box.text("inner.yaml", f'runner: "subprocess:getoutput"\naxes: [{{name: cmd, values: '
                           f'["touch {box.outside}/owned"]}}]\n')
    return "inner.yaml"


def engine_study(box, runner="nlos_cl.sweep.engine:sweep"):
    return (f"runner: {runner}\naxes: [{{name: study, values: [{inner(box)}]}}]\n"
            "params: {out: o2, allow_runner: [subprocess]}\n")


def cli_study(box):
    return ("runner: nlos_cl.apps.cli:main\naxes: [{name: argv, values: [[sweep, "
            f"{inner(box)}, --out, o3, --workers, '0', --allow-runner, subprocess]]}}]\n")


def write_study(box):
    box.text("precious.txt", "mine\n")  # in the user's folder: a change is data loss
    return ("runner: nlos_cl.io.safe_write:write_text\naxes: [{name: path, values: "
            "[precious.txt]}]\nparams: {text: gone, what: x, force: true}\n")


def reexport(box):
    box.text("mymod.py", "from nlos_cl.sweep.engine import sweep  # noqa: F401\n")
    return sweep(box, engine_study(box, "mymod:sweep"), "--allow-runner", "mymod")


def secret_file(box, name, text):
    """A file outside the user's folder holding the secret, named by absolute path."""
    path = box.outside / name
    path.write_text(text)
    return path


def shadow_scene(box):
    """A file shaped like /etc/shadow (each line ends in ':', so YAML reads a mapping of 24
    keys), the secret in one of them."""
    lines = [f"user{i}:*:20228:0:99999:7:::" for i in range(23)]
    lines.insert(5, f"root:{SECRET}:20228:0:99999:7:::")
    return sweep(box, f"scene: {secret_file(box, 'shadow', chr(10).join(lines) + chr(10))}\n"
                 + SNR)


def group_scene(box):
    """A file shaped like /etc/group: a line without a trailing ':' is a YAML error there,
    and YAML's error quotes the line (the secret)."""
    lines = [f"g{i}:x:{100 + i}:" for i in range(46)] + [f"users:x:100:{SECRET}"]
    return sweep(box, f"scene: {secret_file(box, 'group', chr(10).join(lines) + chr(10))}\n"
                 + SNR)


def duplicate_key_scene(box):
    text = f"{SECRET}: a\n{SECRET}: a\n"
    return sweep(box, f"scene: {secret_file(box, 'dup.yaml', text)}\n" + SNR)


def slow_runner(box):
    """A user runner that says it started, then sleeps."""
    box.text("slow.py", "import pathlib\nimport time\n\n\ndef run(x):\n"
                        "    pathlib.Path('started').write_text('1')\n    time.sleep(120)\n"
                        "    return x\n")
    return box.text("s.yaml", 'runner: "slow:run"\naxes: [{name: x, values: [1]}]\n')


def busy_folder(box, *extra):
    """A first sweep into work/o, left running (killed after the case), then the second."""
    s = slow_runner(box)
    argv = ["sweep", s, "--out", box.work / "o", *SWEEP0, "--allow-runner", "slow"]
    env = dict(os.environ, PYTHONPATH=str(REPO))
    first = subprocess.Popen([sys.executable, "-m", "nlos_cl.apps.cli", *map(str, argv)],
                             cwd=box.work, env=env, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL)
    box.cleanup.append(["kill", "-9", str(first.pid)])
    deadline = time.monotonic() + 60
    while not (box.work / "started").exists():
        if first.poll() is not None or time.monotonic() > deadline:
            raise RuntimeError(f"the first sweep did not start (exit {first.poll()})")
        time.sleep(0.1)
    return argv + list(extra)


def linked_lock(box):
    """A finished study whose lock file was replaced by a link to a file outside that does
    not exist yet (following the link would create it)."""
    out = done_study(box)
    lock = out / ".sweep.lock"
    if lock.exists() or lock.is_symlink():
        lock.unlink()
    lock.symlink_to(box.outside / "lock")
    return ["sweep", study(box, SNR), "--out", out, "--resume", *SWEEP0]


def deep_record(box):
    out = done_study(box)
    (out / "study.json").write_text("[" * 100_000 + "]" * 100_000)
    return ["sweep", study(box, SNR), "--out", out, "--resume", *SWEEP0]


def alias_bomb_study(box):
    """A 100 kB text aliased 9,000 times: 900 MB of study once expanded."""
    values = ", ".join(f"[*a, {i}]" for i in range(9000))
    return sweep(box, f"description: &a {'x' * LONG}\nscene: {{}}\n"
                      f"axes: [{{path: description, name: d, values: [{values}]}}]\n")


def long_shape(box):
    return sweep(box, f"scene: {{targets: [{{shape: {'q' * LONG}}}], setup: {{detector_spots: "
                      f"[[-0.5, 0, 0]]}}}}\n" + SNR)


def _runner(name, values="[1]", axis="a", extra=""):
    return f"runner: {name}\naxes: [{{name: {axis}, values: {values}}}]\n{extra}"


STEP_FAILED = says("grid.step_m")  # the run's failure is reported, naming the field
L = "l" * LONG

STUDY_CASES = [
    # ---- class 1-8: the runner
    Case(SEC, "study runner nlos_cl.sweep.engine:sweep running a shell study",
         lambda b: sweep(b, engine_study(b))),
    Case(SEC, "study runner nlos_cl.apps.cli:main with a sweep argv",
         lambda b: sweep(b, cli_study(b))),
    Case(SEC, "study runner nlos_cl.io.safe_write:write_text over the user's file",
         lambda b: sweep(b, write_study(b))),
    Case(SEC, "study runner nlos_cl.sweep.engine:sweep under --allow-runner nlos_cl",
         lambda b: sweep(b, engine_study(b), "--allow-runner", "nlos_cl")),
    Case(SEC, "study runner write_text over the user's file under --allow-runner nlos_cl",
         lambda b: sweep(b, write_study(b), "--allow-runner", "nlos_cl")),
    Case(SEC, "a user module re-exporting nlos_cl's sweep, --allow-runner mymod", reexport),
    Case(TB, "study runner through an array's property (closed:BOX_YAWS.mT)",
         lambda b: sweep(b, _runner("nlos_cl.localization.model.policy.closed:BOX_YAWS.mT"))),
    Case(SEC, "study runner paper_target.__globals__",
         lambda b: sweep(b, _runner("nlos_cl.sweep.examples:paper_target.__globals__"))),
    Case(SEC, "study runner paper_target.__call__",
         lambda b: sweep(b, _runner("nlos_cl.sweep.examples:paper_target.__call__", "[3.0]",
                                    "x"))),
    Case(VAGUE, "a 100 kB study runner name",
         lambda b: sweep(b, _runner(f'"nlos_cl.{"a" * LONG}:run"'))),
    # ---- class 9-11: a file outside named as the scene
    Case(SEC, "a study whose scene is a shadow-like file of secrets (a mapping)", shadow_scene),
    Case(SEC, "a study whose scene is a group-like file (a YAML error at a secret)",
         group_scene),
    Case(SEC, "a study whose scene file repeats a secret key", duplicate_key_scene),
    # ---- class 12-13: the folder lock
    Case(DL, "sweep --resume into a folder another sweep is writing",
         lambda b: busy_folder(b, "--resume")),
    Case(DL, "sweep into a folder another sweep is writing", busy_folder),
    Case(SEC, "sweep --resume whose OUT/.sweep.lock links to a file outside", linked_lock),
    # ---- class 14-20: axes that overwrite each other or repeat
    Case(WRONG, "two study axes on one path",
         lambda b: based(b, "axes: [{path: noise.snr_db, values: [0, 10]}, {path: "
                            "noise.snr_db, name: s2, values: [1, 2]}]\n")),
    Case(WRONG, "a study axis on a key inside another axis's key",
         lambda b: based(b, 'axes: [{path: "targets[0].position", values: [[3, 2, 0]]}, '
                            '{path: "targets[0].position[1]", name: y, values: [1, 2]}]\n')),
    Case(WRONG, "a study axis on estimator beside the implicit estimators",
         lambda b: based(b, "axes: [{path: estimator, name: e, values: [paper, model]}]\n")),
    Case(WRONG, "a study axis on seed beside the implicit seeds",
         lambda b: based(b, "axes: [{path: seed, name: s, values: [1, 2]}]\n")),
    Case(WRONG, "a study axis holding 0 and 0.0",
         lambda b: based(b, "axes: [{path: noise.snr_db, values: [0, 10, 0.0]}]\n")),
    Case(WRONG, "a study range whose step rounds to repeats",
         lambda b: based(b, "axes: [{path: h_s, range: {start: 0, stop: 1.0e-12, step: "
                            "1.0e-13}}]\n")),
    Case(WRONG, "a study zip repeating a combination",
         lambda b: based(b, "axes: [{zip: [{path: noise.snr_db, values: [0, 0]}, {path: h_s, "
                            "values: [1.0e-9, 1.0e-9]}]}]\n")),
    Case(WRONG, "study seeds [3, 1, 3]", lambda b: based(b, "seeds: [3, 1, 3]\n" + SNR)),
    Case(WRONG, "study estimators [paper, model, paper]",
         lambda b: based(b, "estimators: [paper, model, paper]\n" + SNR)),
    # ---- class 21-22: grids the search cannot score
    Case(WRONG, "a study grid at a 1e-5 m step over 6 x 6 m",
         lambda b: based(b, "grid: {x: [0, 6], y: [0.01, 6], step_m: 1.0e-5}\n" + SNR)),
    Case(TB, "a study grid step of 5e-324",
         lambda b: based(b, "grid: {x: [0, 6], y: [0.01, 6], step_m: 5.0e-324}\n" + SNR)),
    Case(TB, "a study grid step that is text ('0.01')",
         lambda b: based(b, "grid: {x: [0, 6], y: [0.01, 6], step_m: \"0.01\"}\n" + SNR)),
    Case(WRONG, "paper_target runs with step_m 1e-5",
         lambda b: sweep(b, _runner("nlos_cl.sweep.examples:paper_target", "[3.0]", "x",
                                    "seeds: 1\nparams: {step_m: 1.0e-5}\n")),
         ok=STEP_FAILED),
    # ---- class 23-29: deep, bloated and mistyped study input (25 is Python only)
    Case(TB, "a 100,000-deep study file (JSON)",
         lambda b: sweep(b, "[" * 100_000 + "]" * 100_000, name="s.json")),
    Case(TB, "sweep --resume with a 100,000-deep OUT/study.json", deep_record),
    Case(MEM, "a study alias bomb (100 kB aliased 9,000 times)", alias_bomb_study),
    Case(VAGUE, "a 100 kB target shape quoted by the scene checker", long_shape),
    Case(VAGUE, "a 100 kB study batch_size", lambda b: based(b, f"batch_size: {L}\n" + SNR)),
    Case(VAGUE, "100 kB study seeds", lambda b: based(b, f"seeds: {L}\n" + SNR)),
    Case(VAGUE, "a 100 kB study h_s", lambda b: based(b, f"h_s: {L}\n" + SNR)),
    Case(VAGUE, "a 100 kB unknown axis key",
         lambda b: based(b, f"axes: [{{path: noise.snr_db, values: [10], ? {L} : 1}}]\n")),
    Case(VAGUE, "a 100 kB axis name",
         lambda b: based(b, f"axes: [{{path: noise.snr_db, name: {L}, values: [10]}}]\n")),
    Case(VAGUE, "a 100 kB axis path", lambda b: based(b, f"axes: [{{path: {L}, values: [10]}}]\n")),
    Case(TB, "study record [[1]]", lambda b: based(b, "record: [[1]]\n" + SNR)),
    Case(TB, "a study axis with keys 1 and b (mixed types)",
         lambda b: based(b, "axes: [{path: noise.snr_db, values: [10], 1: 2, b: 3}]\n")),
]
