"""Where one in-process `nl.locate_capture(frame)` of the paper's scene spends its time, stage by
stage, before and after a change, in one process (issue 23: the model estimate <= 20 ms a frame,
<= 15x the paper's argmax).

    .venv/bin/python scripts/model_stages.py [--runs 15] [--baseline REV] [--seed 0] [--cpu]
        [--after PATH...]
    .venv/bin/python scripts/model_stages.py --positions [--draws 10]

The baseline is REV's nlos_cl (default HEAD), extracted with `git archive` into a temporary
folder as the package `nlos_cl_before` and imported beside this checkout's: each run calls both
(the order alternating run by run) and the paper's argmax (`estimator="paper"`) with each, on
the same frame (pickled across: the same bytes). Stages are inclusive times (wall, or with
--cpu the process's CPU time, steadier on a shared machine) of the estimator's steps (wrapped
functions; the short fits are select.fit with SHORT_NFEV), the rest of the estimator, and
everything outside it. Printed: median [quartiles] per stage, ms; the total over the paper's
argmax run by run; plate evaluations and minor page faults per locate.

--after PATH...: "after" is the baseline with only these files from the working tree (other
work in progress left out); default: the working tree's nlos_cl as it is.

--positions: the positions of both on the paper's scene (seeds 0-2) and on the draws
`reproduce draws` re-runs as rerun("one", i), i < --draws: the largest difference, mm.
"""
from __future__ import annotations

import argparse
import functools
import importlib
import io
import pickle
import resource
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
BEFORE = "nlos_cl_before"
STAGES = ("observation", "start centres", "start candidates", "short fits", "final fit",
          "covariance", "estimator, rest", "estimator", "outside the estimator", "total",
          "total, CPU time")


def load_tree(rev: str, folder: Path, name: str, overlay=()):
    """REV's nlos_cl as the package `name`, its kernels/ beside it (as in a checkout), with the
    files `overlay` (paths in this checkout, e.g. nlos_cl/localization/model/forward/data.py) copied
    over it from the working tree."""
    folder.mkdir()
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "nlos_cl", "kernels"],
                             check=True, capture_output=True).stdout
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(folder, filter="data")
    for path in overlay:
        (folder / path).write_bytes((ROOT / path).read_bytes())
    (folder / "nlos_cl").rename(folder / name)
    sys.path.insert(0, str(folder))
    return importlib.import_module(name)


class _Renamed(pickle.Unpickler):
    def __init__(self, data, name):
        super().__init__(data)
        self.name = name

    def find_class(self, module, name):
        if module.split(".")[0] == "nlos_cl":
            module = self.name + module[len("nlos_cl"):]
        return super().find_class(module, name)


def as_package(value, pkg):
    """An object of this checkout's nlos_cl as package `pkg`'s (the same numbers)."""
    if pkg.__name__ == "nlos_cl":
        return value
    return _Renamed(io.BytesIO(pickle.dumps(value)), pkg.__name__).load()


class Clock:
    """Inclusive seconds per stage of one package's estimator, reset per locate."""

    def __init__(self, pkg, now=time.perf_counter):
        self.seconds, self.now = {}, now
        def mod(name):
            return importlib.import_module(f"{pkg.__name__}.localization.model.{name}")
        select, estimator = mod("select"), mod("estimator")
        short = select.SHORT_NFEV
        self._wrap(mod("data") if hasattr(mod("data"), "observation") else estimator,
                   "observation", lambda *a, **k: "observation")
        self._wrap(mod("starts"), "start_centres", lambda *a, **k: "start centres")
        self._wrap(mod("starts"), "best_starts", lambda *a, **k: "start candidates")
        self._wrap(select, "fit", lambda *a, **k: "short fits" if (
            a[3] if len(a) > 3 else k.get("max_nfev")) == short else "final fit")
        self._wrap(estimator, "covariance", lambda *a, **k: "covariance")
        self._wrap(estimator.ModelEstimator, "estimate", lambda *a, **k: "estimator")

    def _wrap(self, module, name, stage_of):
        original = getattr(module, name)

        @functools.wraps(original)
        def timed(*args, **kwargs):
            start = self.now()
            try:
                return original(*args, **kwargs)
            finally:
                stage = stage_of(*args, **kwargs)
                self.seconds[stage] = self.seconds.get(stage, 0.0) + self.now() - start
        setattr(module, name, timed)


def one_locate(pkg, clock, frame) -> dict:
    clock.seconds = {}
    faults, cpu = resource.getrusage(resource.RUSAGE_SELF).ru_minflt, time.process_time()
    start = clock.now()
    cap = pkg.locate_capture(frame)
    total = clock.now() - start
    cpu = time.process_time() - cpu
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults
    fit = cap.points[0].location.targets[0].fit
    est = clock.seconds.pop("estimator")
    out = dict(clock.seconds, total=total, estimator=est)
    out["estimator, rest"] = est - sum(clock.seconds.values())
    out["outside the estimator"] = total - est
    out["forward calls"] = fit.timings_s["forward_calls"]
    out["total, CPU time"], out["page faults"] = cpu, faults
    return out


def paper_locate(pkg, frame, now=time.perf_counter) -> float:
    start = now()
    pkg.locate_capture(frame, estimator="paper")
    return now() - start


def _quartiles(values) -> str:
    q = statistics.quantiles(values, n=4) if len(values) > 1 else [values[0]] * 3
    return f"{1e3 * q[1]:7.2f} [{1e3 * q[0]:.2f}-{1e3 * q[2]:.2f}]"


def bench(pkgs, frames, runs: int, now=time.perf_counter) -> None:
    clocks = {k: Clock(p, now) for k, p in pkgs.items()}
    rows = {k: [] for k in pkgs}
    paper = {k: [] for k in pkgs}
    for k, p in pkgs.items():  # warm-up: programs, plans, the first-call costs
        one_locate(p, clocks[k], frames[k])
        paper_locate(p, frames[k])
    for run in range(runs):
        order = list(pkgs) if run % 2 == 0 else list(pkgs)[::-1]
        for k in order:
            rows[k].append(one_locate(pkgs[k], clocks[k], frames[k]))
            paper[k].append(paper_locate(pkgs[k], frames[k], now))
    what = "CPU time (process_time)" if now is time.process_time else "wall time"
    print(f"{runs} interleaved runs, {what}, ms: median [quartiles]")
    print(f"{'stage':26s}" + "".join(f"{k:>30s}" for k in pkgs))
    for stage in STAGES:
        print(f"{stage:26s}" + "".join(
            f"{_quartiles([r.get(stage, 0.0) for r in rows[k]]):>30s}" for k in pkgs))
    print(f"{'paper argmax (locate)':26s}" + "".join(f"{_quartiles(paper[k]):>30s}"
                                                     for k in pkgs))
    for k in pkgs:
        ratio = [r["total"] / q for r, q in zip(rows[k], paper[k])]
        calls = statistics.median(r["forward calls"] for r in rows[k])
        faults = statistics.median(r["page faults"] for r in rows[k])
        print(f"{k}: total / paper argmax per run, median {statistics.median(ratio):.2f} "
              f"[{min(ratio):.2f}-{max(ratio):.2f}]; plate evaluations {calls:g}; minor page "
              f"faults per locate {faults:g}")


def paper_frame(nl, seed: int):
    return nl.add_noise(nl.simulate(nl.paper_scene()), 10.0, seed=seed).histograms()


def draw_frames(count: int):
    """(label, frame) of rerun("one", i): the draw simulated and noised as the study does."""
    from nlos_cl.apps.reproduce import draws_gen, draws_scene
    from nlos_cl.apps.reproduce.common import Settings
    out = []
    for i in range(count):
        d = draws_gen.draw("one", i, None)
        clean, _ = draws_scene.simulate(d, Settings())
        out.append((f"draw one {i}", draws_scene.noisy(clean, d),
                    np.array([t["centre"] for t in d["targets"]], float)))
    return out


def positions(pkgs, count: int) -> None:
    import nlos_cl as nl
    cases = [(f"paper seed {s}", frame, np.reshape(frame.truth, (-1, 3)))
             for s in range(3) for frame in [paper_frame(nl, s)]]
    cases += draw_frames(count)
    worst = 0.0
    for label, frame, truth in cases:
        found = {}
        for k, p in pkgs.items():
            f = as_package(frame, p)
            cap = p.locate_capture(f)
            found[k] = np.array([t.position for t in cap.points[0].location.targets], float)
        same = found["after"].shape == found["before"].shape
        diff = float(np.abs(found["after"] - found["before"]).max()) if same else np.inf
        err = float(np.linalg.norm(found["after"][0] - truth[0])) if len(found["after"]) else np.nan
        worst = max(worst, diff)
        print(f"{label:16s} after {np.round(found['after'][0], 5)} before "
              f"{np.round(found['before'][0], 5)} |diff| {1e3 * diff:.4f} mm, "
              f"error (after) {1e3 * err:.1f} mm")
    print(f"largest difference {1e3 * worst:.4f} mm")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=15)
    ap.add_argument("--baseline", default="HEAD")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--positions", action="store_true")
    ap.add_argument("--draws", type=int, default=10)
    ap.add_argument("--cpu", action="store_true", help="stages in CPU time (process_time, all "
                    "threads) instead of wall time: steadier on a shared machine")
    ap.add_argument("--after", nargs="*", metavar="PATH", help="after = the baseline with "
                    "these working-tree files only (default: the working tree as it is)")
    args = ap.parse_args(argv)
    import nlos_cl as nl
    with tempfile.TemporaryDirectory() as tmp:
        pkgs = {"before": load_tree(args.baseline, Path(tmp) / "a", BEFORE)}
        pkgs["after"] = nl if args.after is None else \
            load_tree(args.baseline, Path(tmp) / "b", "nlos_cl_after", args.after)
        if args.positions:
            positions(pkgs, args.draws)
            return
        frame = paper_frame(nl, args.seed)
        bench(pkgs, {k: as_package(frame, p) for k, p in pkgs.items()}, args.runs,
              time.process_time if args.cpu else time.perf_counter)


if __name__ == "__main__":
    main()
