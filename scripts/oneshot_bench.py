"""How far a one-shot `nlos-cl locate F.h5 --json` is from the start-up floor (issue 23 item 4).

    .venv/bin/python scripts/oneshot_bench.py [--rounds 9] [--baseline SRC] [--stage-runs 5]
        [--profile N] [--keep-env]

F.h5 is the paper's scene (`nlos-cl simulate --snr-db 10`, made in a temporary folder). Whole
processes, interleaved round by round (the order rotates each round): the floor (Python, NumPy,
h5py, pyopencl, an OpenCL context and queue: nothing of nlos_cl), `nlos-cl locate F.h5 --json`
and `--estimator paper`; with --baseline SRC (a source tree, e.g. `git archive HEAD | tar -x -C
SRC`) the same two commands again with SRC first on PYTHONPATH, and whether their JSON equals
this checkout's (or --candidate's, a second tree run the same way). Then one locate taken apart: `-X importtime` summed per top-level package
(beside the floor's), and perf_counter stages (exclusive times, median of --stage-runs).

Bytecode: PYTHONDONTWRITEBYTECODE is dropped and PYTHONPYCACHEPREFIX points into the temporary
folder, so every variant runs from cached .pyc as an installed package does (--keep-env runs in
the caller's environment as it is). One warm-up round, not counted, fills that cache and the
OpenCL kernel cache.
"""
from __future__ import annotations

import argparse
import collections
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FLOOR = ("import numpy, h5py, pyopencl as cl; "
         "ctx = cl.create_some_context(interactive=False); q = cl.CommandQueue(ctx)")
FLOOR_QUICK_EXIT = FLOOR + "; import os, sys; sys.stdout.flush(); os._exit(0)"
NLOS_CL = [sys.executable, "-m", "nlos_cl.apps.cli"]
SCRIPT = str(Path(__file__).resolve())

# (module, attribute path, stage): timed as each module finishes loading, so that loading it is
# still counted under "imports". Times are exclusive: a stage inside another is not counted twice.
STAGES = [
    ("nlos_cl.apps.cli", "parser", "argument parser"),
    ("nlos_cl.device.runtime", "Runtime.__init__", "device, context, queue"),
    ("nlos_cl.device.runtime", "Runtime.kernel", "programs (from the kernel cache)"),
    ("nlos_cl.io.ytal.capture", "read_capture_with_frame", "capture read and checks"),
    ("nlos_cl.localization.measured", "process_capture", "measured-data processing"),
    ("nlos_cl.localization.capture", "_estimator", "estimator set-up"),  # trees before 9fd64f4
    ("nlos_cl.localization.capture", "choose_estimator", "estimator set-up"),
    ("nlos_cl.localization.capture", "search_region", "search region"),
    ("nlos_cl.ops.signals", "upload", "upload, filter, search"),
    ("nlos_cl.localization.capture", "gauss_filter", "upload, filter, search"),
    ("nlos_cl.localization.locator", "Locator.__call__", "upload, filter, search"),
    ("nlos_cl.localization.locator", "reachable_bins", "detection"),
    ("nlos_cl.localization.locator", "detected_in", "detection"),
    ("nlos_cl.localization.locator", "_estimate", "fit (estimator)"),
    ("nlos_cl.localization.capture", "PointLocation.as_json", "report (JSON)"),
    ("nlos_cl.localization.capture", "CaptureLocation.as_json", "report (JSON)"),
]


# ----------------------------------------------------------------- inside the measured process
class Stages:
    """Exclusive wall time per stage: time spent in a stage nested in another is the inner's."""

    def __init__(self):
        self.seconds = collections.defaultdict(float)
        self._stack = []  # [stage, start, time inside nested stages]

    def timed(self, stage, function):
        def run(*args, **kwargs):
            self._stack.append([stage, time.perf_counter(), 0.0])
            try:
                return function(*args, **kwargs)
            finally:
                name, start, inner = self._stack.pop()
                spent = time.perf_counter() - start
                self.seconds[name] += spent - inner
                if self._stack:
                    self._stack[-1][2] += spent
        return run


def _patch(stages, module, attribute, stage):
    owner, _, name = attribute.rpartition(".")
    holder = getattr(module, owner) if owner else module
    if hasattr(holder, name):  # a stage's function under another tree's name is skipped
        setattr(holder, name, stages.timed(stage, getattr(holder, name)))


def child_stages(capture: str, result_path: str, profile: int) -> None:
    """Run `nlos-cl locate capture --json` in this process with the stages timed; write them."""
    begin = time.time()
    import importlib._bootstrap as bootstrap
    stages, pending = Stages(), collections.defaultdict(list)
    for module, attribute, stage in STAGES:
        pending[module].append((attribute, stage))
    find_and_load = bootstrap._find_and_load

    def loading(name, *args):
        module = find_and_load(name, *args)
        for attribute, stage in pending.pop(name, ()):
            _patch(stages, module, attribute, stage)
        return module
    # CPython looks _find_and_load up on importlib._bootstrap for every import statement
    bootstrap._find_and_load = stages.timed("imports", loading)
    main = stages.timed("other (CLI, checks, glue)", lambda: _run_cli(capture))
    if profile:
        import cProfile
        import pstats
        profiler = cProfile.Profile()
        profiler.runcall(main)
        pstats.Stats(profiler, stream=sys.stderr).sort_stats("tottime").print_stats(profile)
    else:
        main()
    bootstrap._find_and_load = find_and_load
    Path(result_path).write_text(json.dumps({"begin": begin, "end": time.time(),
                                             "stages": stages.seconds}))


def _run_cli(capture):
    import contextlib
    import io
    from nlos_cl.apps import cli
    with contextlib.redirect_stdout(io.StringIO()):
        cli.main(["locate", capture, "--json"])


# ----------------------------------------------------------------- the measuring process
def environment(tmp: Path, keep: bool, baseline: str | None = None) -> dict:
    env = dict(os.environ)
    if not keep:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = str(tmp / "pycache")
    if baseline:
        env["PYTHONPATH"] = os.pathsep.join(p for p in (baseline, env.get("PYTHONPATH")) if p)
    return env


def variants(capture: str, env: dict, baseline: str | None, keep: bool, tmp: Path) -> dict:
    """name: (argv, environment)."""
    locate = [*NLOS_CL, "locate", capture, "--json"]
    out = {"floor (imports, context, queue)": ([sys.executable, "-c", FLOOR], env),
           # the same, leaving as `nlos-cl` does (terminal.leave): how much of the floor is its exit
           "floor, leaving with os._exit": ([sys.executable, "-c", FLOOR_QUICK_EXIT], env),
           "locate --json": (locate, env),
           "locate --json --estimator paper": ([*locate, "--estimator", "paper"], env)}
    if baseline:
        old = environment(tmp, keep, baseline)
        out["baseline: locate --json"] = (locate, old)
        out["baseline: locate --json --estimator paper"] = ([*locate, "--estimator", "paper"], old)
    return out


def run_rounds(runs: dict, rounds: int) -> tuple[dict, dict]:
    """Wall seconds per variant over `rounds` interleaved rounds (after one warm-up), and each
    variant's stdout (which must be the same every round)."""
    names, outputs = list(runs), {}
    walls = {name: [] for name in names}  # the table's order: the floor first
    for r in range(rounds + 1):
        order = names[r % len(names):] + names[:r % len(names)]
        for name in order:
            argv, env = runs[name]
            start = time.perf_counter()
            done = subprocess.run(argv, env=env, capture_output=True, text=True)
            wall = time.perf_counter() - start
            if done.returncode != 0:
                raise SystemExit(f"{name} failed ({done.returncode}): {done.stderr[-2000:]}")
            if outputs.setdefault(name, done.stdout) != done.stdout:
                raise SystemExit(f"{name}: the output changed between rounds")
            if r > 0:  # round 0 fills the bytecode and kernel caches
                walls[name].append(wall)
    return walls, outputs


def wall_table(walls: dict) -> str:
    floor = statistics.median(next(iter(walls.values())))
    lines = ["| variant | wall s, median (min-max) | x floor |", "|---|---:|---:|"]
    for name, w in walls.items():
        med = statistics.median(w)
        lines.append(f"| {name} | {med:.3f} ({min(w):.3f}-{max(w):.3f}) | {med / floor:.2f} |")
    return "\n".join(lines)


def json_check(outputs: dict) -> list[str]:
    said = []
    for name, text in outputs.items():
        if name.startswith("baseline: "):
            same = json.loads(text) == json.loads(outputs[name[len("baseline: "):]])
            said.append(f"{name[len('baseline: '):]}: JSON {'identical' if same else 'DIFFERS'}"
                        " to the baseline's")
    return said


def import_times(argv: list, env: dict, runs: int = 3) -> collections.Counter:
    """-X importtime's self times (s) summed per top-level package (nlos_cl per subpackage),
    the median of `runs` processes."""
    per_run = []
    for _ in range(runs):
        done = subprocess.run([argv[0], "-X", "importtime", *argv[1:]], env=env,
                              capture_output=True, text=True)
        totals = collections.Counter()
        for line in done.stderr.splitlines():
            found = re.match(r"import time:\s+(\d+) \|\s+\d+ \|\s*(\S+)", line)
            if found:
                parts = found.group(2).split(".")
                top = ".".join(parts[:2]) if parts[0] == "nlos_cl" and len(parts) > 1 \
                    else parts[0]
                totals[top] += int(found.group(1)) * 1e-6
        per_run.append(totals)
    names = set().union(*per_run)
    return collections.Counter({n: statistics.median(t[n] for t in per_run) for n in names})


def import_table(floor: collections.Counter, locate: collections.Counter, top: int = 14) -> str:
    lines = ["| package | floor ms | locate ms |", "|---|---:|---:|"]
    for name, seconds in locate.most_common(top):
        lines.append(f"| {name} | {1e3 * floor[name]:.1f} | {1e3 * seconds:.1f} |")
    rest = sorted(set(locate) | set(floor))
    lines.append(f"| all ({len(rest)} packages) | {1e3 * sum(floor.values()):.1f} | "
                 f"{1e3 * sum(locate.values()):.1f} |")
    return "\n".join(lines)


def stage_table(capture: str, env: dict, tmp: Path, runs: int, profile: int) -> str:
    """perf_counter stages of `runs` locates in this script's child mode, medians (min-max)."""
    per_stage = collections.defaultdict(list)
    for i in range(runs):
        result = tmp / f"stages{i}.json"
        argv = [sys.executable, SCRIPT, "--child-stages", capture, str(result),
                "--profile", str(profile if i == 0 else 0)]
        start = time.time()
        done = subprocess.run(argv, env=env, capture_output=not (profile and i == 0), text=True)
        stop = time.time()
        if done.returncode != 0:
            raise SystemExit(f"stage run failed: {done.stderr[-2000:]}")
        got = json.loads(result.read_text())
        per_stage["python start (interpreter, site, this script's stdlib)"].append(got["begin"] - start)
        for name, seconds in got["stages"].items():
            per_stage[name].append(seconds)
        per_stage["exit (interpreter, OpenCL teardown)"].append(stop - got["end"])
        per_stage["whole process"].append(stop - start)
    lines = ["| stage | ms, median (min-max) |", "|---|---:|"]
    for name, values in sorted(per_stage.items(), key=lambda kv: -statistics.median(kv[1])):
        lines.append(f"| {name} | {1e3 * statistics.median(values):.1f} "
                     f"({1e3 * min(values):.1f}-{1e3 * max(values):.1f}) |")
    return "\n".join(lines)


def make_capture(tmp: Path, env: dict) -> str:
    path = tmp / "F.h5"
    subprocess.run([*NLOS_CL, "simulate", "--snr-db", "10", "--out", str(path)], env=env,
                   check=True, capture_output=True)
    return str(path)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--rounds", type=int, default=9)
    p.add_argument("--baseline", default=None, help="a source tree to compare against")
    p.add_argument("--candidate", default=None, help="a source tree to run in place of the "
                   "installed nlos_cl (e.g. the baseline with one change)")
    p.add_argument("--stage-runs", type=int, default=5)
    p.add_argument("--profile", type=int, default=0, help="also print cProfile's top N")
    p.add_argument("--keep-env", action="store_true", help="no bytecode cache of our own")
    p.add_argument("--child-stages", nargs=2, metavar=("CAPTURE", "RESULT"), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child_stages:
        child_stages(*args.child_stages, args.profile)
        from nlos_cl.apps import terminal
        if hasattr(terminal, "leave"):  # a tree with the quick exit leaves as `nlos-cl` does
            import atexit
            sys.stdout.flush()
            sys.stderr.flush()
            atexit._run_exitfuncs()
            os._exit(0)
        return 0
    here = os.getcwd()
    with tempfile.TemporaryDirectory(prefix="oneshot_bench-") as folder:
        tmp = Path(folder)
        # every process runs in the temporary folder: `python -m` puts the working directory
        # first on sys.path, which would shadow --baseline's tree with a checkout's nlos_cl
        os.chdir(tmp)
        env = environment(tmp, args.keep_env, args.candidate)
        capture = make_capture(tmp, env)
        with open("/proc/loadavg") as fh:
            load = " ".join(fh.read().split()[:3])
        runs = variants(capture, env, args.baseline, args.keep_env, tmp)
        walls, outputs = run_rounds(runs, args.rounds)
        print(f"{args.rounds} interleaved rounds, load average before: {load}, after: "
              f"{' '.join(open('/proc/loadavg').read().split()[:3])}\n")
        print(wall_table(walls), *json_check(outputs), sep="\n")
        print("\n-X importtime, self times summed per package:\n")
        print(import_table(import_times([sys.executable, "-c", FLOOR], env),
                           import_times(runs["locate --json"][0], env)))
        print(f"\nStages of one locate (exclusive, {args.stage_runs} runs):\n")
        print(stage_table(capture, env, tmp, args.stage_runs, args.profile))
        os.chdir(here)
    return 0


if __name__ == "__main__":
    sys.exit(main())
