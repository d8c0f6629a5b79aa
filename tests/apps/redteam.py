"""The red team: every hostile input class, each input run as `nlos-cl` in its own
subprocess (30 s timeout, 4 GiB address-space limit, its own sandbox under a temporary folder:
the repository is never touched), and each outcome classified:

  clear           exit != 0 and one line on stderr that names a field and says how to fix it
  correct         exit 0 with the right answer (or the warning that was due)
  traceback       a Python traceback, or death by a signal (segfault, abort)
  hang            still running after the timeout
  memory          killed (SIGKILL: the OOM killer) or a MemoryError / std::bad_alloc
  data loss       a file that was in the user's folder before the run changed or went
  security        a file outside the sandbox read (its secret in the output) or changed, or
                  code run (a file appeared outside)
  silently wrong  exit 0 with a wrong answer, or with a refusal or warning that was due missing
  vague           exit != 0 but no one line with a field and a fix

    python tests/apps/redteam.py                         # the table and a count per outcome
    python tests/apps/redteam.py --only security --only hangs
    python tests/apps/redteam.py --case 3 --case 17      # by number in the table
    python tests/apps/redteam.py --out docs/results/redteam/redteam.md   # the page, generated
    python tests/apps/redteam.py --strict                # exit 1 unless all clear / correct

It is a report: the exit status is 0 whatever it finds, unless --strict.
"""
from __future__ import annotations

import argparse
import hashlib
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from redteam_cases import CASES, SECRET, STUDY, Box, Case  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
TIMEOUT_S = 30.0
OUTCOMES = ["clear", "correct", "traceback", "hang", "memory", "data loss", "security",
            "silently wrong", "vague", "not run"]
GOOD = {"clear", "correct"}


def cli_command(*args) -> list[str]:
    """`nlos-cl ARGS`; a case whose first argument is "api" calls the Python API instead
    (redteam_api.py: nl.FUNCTION(PATH, ...), its InputError on one line)."""
    if args and args[0] == "api":
        return [sys.executable, str(Path(__file__).resolve().parent / "redteam_api.py"),
                *map(str, args[1:])]
    return [sys.executable, "-m", "nlos_cl.apps.cli", *map(str, args)]


def child_env(case: Case, box: Box) -> dict:
    env = dict(os.environ, HOME=str(box.work.parent / "home"), PYTHONPATH=str(REPO),
               PYTHONUNBUFFERED="1", XDG_CACHE_HOME=os.environ.get(
                   "XDG_CACHE_HOME", str(Path(tempfile.gettempdir()) / "nlos_cl-redteam-cache")))
    env.pop("NLOS_CL_VERBOSE", None)
    if case.name.startswith("HOME is a file"):
        (box.work.parent / "home-file").write_text("not a folder")
        env.update(HOME=str(box.work.parent / "home-file"))
        env.pop("XDG_CACHE_HOME")
    return env


def _limits(case: Case):
    def apply():
        resource.setrlimit(resource.RLIMIT_AS, (case.limit_as, case.limit_as))
    return apply


def run_child(argv, env, cwd, case: Case, timeout=TIMEOUT_S):
    """(exit status or None on timeout, stdout, stderr, seconds); the whole process group
    (Dask workers included) is killed at the timeout."""
    start = time.perf_counter()
    proc = subprocess.Popen(argv, cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True,
                            errors="replace", preexec_fn=_limits(case), start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout)
        rc = proc.returncode
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        rc = None
    return rc, out, err, time.perf_counter() - start


def snapshot(folder: Path) -> dict:
    """Each file's identity and content hash (links as their target text), for before/after."""
    seen = {}
    for path in sorted(folder.rglob("*")):
        try:
            if path.is_symlink():
                seen[path] = ("link", os.readlink(path))
            elif path.is_file():
                seen[path] = ("file", hashlib.sha256(path.read_bytes()).hexdigest())
            elif not path.is_dir():
                seen[path] = ("special", path.stat().st_mode)
        except OSError:
            seen[path] = ("unreadable",)
    return seen


def changed(before: dict, after: dict, only_before=False) -> list[str]:
    keys = before if only_before else before.keys() | after.keys()
    return sorted(str(k) for k in keys if before.get(k) != after.get(k))


def error_lines(err: str) -> list[str]:
    """stderr without warning lines and the noise of a library's progress bar."""
    return [ln for ln in err.splitlines() if ln.strip() and "warning:" not in ln
            and not re.match(r"^\s*\d+%\|", ln)]


MAX_CLEAR_CHARS = 600  # the longest clear line in the catalogue is ~420 characters


def is_clear(lines: list[str]) -> bool:
    """One line, naming a field (`nlos-cl: FIELD: ...` or argparse's `argument --x:`) and a fix
    (`Fix:`, or argparse's list of choices)."""
    if len(lines) != 1 or len(lines[0]) > MAX_CLEAR_CHARS:  # an echoed 100 kB value is vague
        return False
    line = lines[0]
    names_field = re.match(r"^nlos-cl(?: \w+)?: (?:argument )?\S.{0,160}?: \S", line)
    return bool(names_field) and ("Fix:" in line or "choose from" in line)


def classify(case: Case, rc, out, err, lost, leaked) -> str:
    if rc is None:
        return "hang"
    if leaked:
        return "security"
    if lost:
        return "data loss"
    if rc == -signal.SIGKILL or re.search(r"MemoryError|bad_alloc|Cannot allocate", err):
        return "memory"
    if rc < 0 or "Traceback (most recent call last)" in err:
        return "traceback"
    if rc in case.answer_codes:
        if case.ok is not None and case.ok(out, err):
            return "correct"
        if rc == 0:
            return "silently wrong"
    return "clear" if is_clear(error_lines(err)) else "vague"


def try_case(case: Case, fixtures, root: Path) -> dict:
    sandbox = Path(tempfile.mkdtemp(prefix="case-", dir=root))
    box = Box(sandbox / "work", sandbox / "outside", fixtures)
    for folder in (box.work, box.outside, sandbox / "home"):
        folder.mkdir()
    (box.outside / "secret.txt").write_text(SECRET + "\n")
    (box.outside / "thesis.h5").write_bytes(b"the user's thesis data\n")
    try:
        argv = case.make(box)
    except Exception as exc:  # the red team's own builder failed: say so, go on
        _clean(box, sandbox)
        return {"class": case.cls, "input": case.name, "outcome": "not run", "seconds": 0.0,
                "detail": f"building the input failed: {type(exc).__name__}: {exc}"[:160]}
    env = child_env(case, box)
    work_before, outside_before = snapshot(box.work), snapshot(box.outside)
    lock = h5py.File(box.work / case.lock, "a") if case.lock else None
    try:
        rc, out, err, seconds = run_child(cli_command(*argv), env, box.work, case)
    finally:
        if lock is not None:
            lock.close()
    lost = changed(work_before, snapshot(box.work), only_before=True)
    leaked = changed(outside_before, snapshot(box.outside)) or (SECRET in out + err)
    outcome = classify(case, rc, out, err, lost, leaked)
    _clean(box, sandbox)
    lines = error_lines(err)
    detail = (lines[-1] if lines else out.strip().splitlines()[-1] if out.strip() else "")
    detail = detail.replace(str(box.work), "WORK").replace(str(box.outside), "OUTSIDE")
    return {"class": case.cls, "input": case.name, "outcome": outcome,
            "seconds": round(seconds, 1), "detail": detail[:160]}


def _clean(box: Box, sandbox: Path) -> None:
    for command in box.cleanup:  # e.g. unmount a tiny disk
        subprocess.run(command, capture_output=True, timeout=30)
    shutil.rmtree(sandbox, ignore_errors=True)


class Fixtures:
    """The inputs cases start from, each made with nlos-cl itself the first time a case asks
    for it (so a few quick cases need none)."""

    STEPS = {"cap.h5": ["simulate", "--out", "cap.h5", "--facet", "0.05"],
             "seq.h5": ["simulate", "walk.yaml", "--frames", "4", "--out", "seq.h5"],
             "noisy.h5": ["simulate", "--out", "noisy.h5", "--facet", "0.05", "--snr-db", "10"],
             "patch.h5": ["simulate", REPO / "docs" / "scenes" / "spad_patch.yaml", "--out",
                          "patch.h5"],
             "study_out": ["sweep", "study.yaml", "--out", "study_out", "--workers", "0",
                           "--no-progress"]}

    def __init__(self, folder: Path):
        self.folder = folder
        shutil.copy(REPO / "docs" / "scenes" / "walk.yaml", folder / "walk.yaml")
        (folder / "study.yaml").write_text(STUDY + "axes: [{path: noise.snr_db, values: [10]}]\n")
        np.savez(folder / "mine.npz", weights=np.arange(3))

    def path(self, name: str) -> Path:
        path = self.folder / name
        if path.exists():
            return path
        if name == "paired.h5":
            _paired_fixture(self.path("cap.h5"), path)
            return path
        step = self.STEPS[name]
        rc, out, err, _ = run_child(cli_command(*step), dict(os.environ, PYTHONPATH=str(REPO)),
                                    self.folder, Case("", "", lambda b: []), timeout=600)
        if rc != 0:
            sys.exit(f"redteam: fixture `nlos-cl {' '.join(map(str, step))}` failed:\n{err}")
        return path


def _paired_fixture(capture: Path, out: Path) -> None:
    """A capture re-labelled as a paired one (a laser per histogram, two distinct)."""
    import nlos_cl as nl
    h = nl.read_capture(capture)
    h = h[0] if isinstance(h, list) else h
    lasers = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.0, 0.0]])
    paired = nl.HistogramSet(h.data, h.time_axis, h.detector_spots, lasers, h.calibration)
    nl.write_capture(out, paired)


def git_head() -> str:
    try:
        head = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"],
                              capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(REPO), "status", "--porcelain", "-uno"],
                               capture_output=True, text=True, check=True).stdout.strip()
        return head + (" with uncommitted changes" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def table(rows: list[dict]) -> str:
    lines = ["| # | class | input | outcome | s | what it said |", "|---|---|---|---|---|---|"]
    for i, r in enumerate(rows, 1):
        said = r["detail"].replace("|", "\\|").replace("`", "'")
        lines.append(f"| {i} | {r['class']} | {r['input']} | {r['outcome']} | {r['seconds']} "
                     f"| {said} |")
    return "\n".join(lines)


def summary(rows: list[dict]) -> str:
    counts = Counter(r["outcome"] for r in rows)
    return ", ".join(f"{counts[o]} {o}" for o in OUTCOMES if counts[o]) + f" ({len(rows)} inputs)"


def page(rows: list[dict]) -> str:
    return (f"# The red team\n\nGenerated by `python tests/apps/redteam.py --out "
            f"docs/results/redteam/redteam.md` (do not edit by hand) at git {git_head()}, "
            f"{time.strftime('%Y-%m-%d')}. Each input runs as `nlos-cl` in its own "
            f"subprocess and sandbox, {TIMEOUT_S:.0f} s timeout, 4 GiB address-space limit; "
            "the outcomes are defined in the script's docstring.\n\n"
            f"**Summary:** {summary(rows)}.\n\n{table(rows)}\n")


def select(args) -> list[Case]:
    chosen = list(enumerate(CASES, 1))
    if args.only:
        chosen = [(i, c) for i, c in chosen if any(o.lower() in c.cls for o in args.only)]
    if args.case:
        chosen = [(i, c) for i, c in chosen if i in args.case]
    if not chosen:
        sys.exit("redteam: --only/--case match no input. Fix: pass a class among "
                 f"{sorted({c.cls for c in CASES})} or a number 1-{len(CASES)}")
    return [c for _, c in chosen]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--only", action="append", default=[], metavar="CLASS",
                   help="only this input class (repeatable; a part of the name will do)")
    p.add_argument("--case", action="append", type=int, default=[], metavar="N",
                   help="only input number N of the full table (repeatable)")
    p.add_argument("--out", help="write the generated page (markdown) here")
    p.add_argument("--strict", action="store_true", help="exit 1 unless all clear / correct")
    args = p.parse_args(argv)
    cases = select(args)
    root = Path(tempfile.mkdtemp(prefix="nlos_cl-redteam-"))
    try:
        (root / "fixtures").mkdir()
        fixtures = Fixtures(root / "fixtures")
        rows = []
        for case in cases:
            rows.append(try_case(case, fixtures, root))
            r = rows[-1]
            print(f"{len(rows):3d} {r['class']:<16} {r['outcome']:<14} {r['seconds']:5.1f} s  "
                  f"{r['input']}", flush=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    print(f"\n{table(rows)}\n\nsummary: {summary(rows)}")
    if args.out:
        Path(args.out).write_text(page(rows), "utf-8")
    return 1 if args.strict and any(r["outcome"] not in GOOD for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
