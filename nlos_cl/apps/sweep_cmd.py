"""`nlos-cl sweep STUDY.yaml --out DIR [--workers N | --scheduler ADDRESS] [--resume]`: a
parameter study as Dask tasks (docs/sweeps.md). `nlos-cl sweep --example` prints a small study.

Also runnable alone: `python -m nlos_cl.apps.sweep_cmd ...` (same arguments)."""
from __future__ import annotations

import argparse
import json
import sys


def _positive_int(field: str, minimum: int = 1):
    def parse(text):
        try:
            value = int(text)
        except ValueError:
            value = -1
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{field}: must be an integer >= {minimum}, got "
                                             f"{text!r}. Fix: pass e.g. 2")
        return value
    return parse


def add_arguments(p) -> None:
    """The command's arguments (cli.py adds them to its `sweep` subparser)."""
    p.add_argument("study", nargs="?", default=None,
                   help="the study file (YAML: a base scene, axes, seeds, estimators)")
    p.add_argument("--out", help="results folder: runs.parquet/, summary.csv, plots")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=_positive_int("--workers", 0), default=None,
                       help="local worker processes (default: one per core; 0: in this "
                       "process, no Dask)")
    where.add_argument("--scheduler", default=None,
                       help="an existing Dask cluster: tcp://HOST:PORT or a scheduler file")
    p.add_argument("--resume", action="store_true",
                   help="finish a study in --out, skipping the runs already written")
    p.add_argument("--batch-size", type=_positive_int("--batch-size"), default=None,
                   help="runs per Dask task (default: from the study, else automatic)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--example", action="store_true",
                   help="print a small runnable study (about 30 s on 2 cores) and exit")
    p.add_argument("--json", action="store_true", help="print one JSON object at the end")
    p.add_argument("--force", action="store_true",
                   help="replace files in --out that no sweep wrote (summary.csv, figures)")
    p.add_argument("--allow-runner", action="append", default=[], metavar="MODULE",
                   help="let the study's `runner:` be a function of MODULE (and its submodules)"
                   ": a study with a runner is a program, so only nlos_cl's own functions run "
                   "without this (repeatable)")


def main(args) -> int:
    from nlos_cl.core.errors import InputError
    from nlos_cl.sweep import example_text, sweep
    if args.example:
        sys.stdout.write(example_text())
        return 0
    if not args.study or not args.out:
        raise InputError("sweep: needs a study file and --out. Fix: nlos-cl sweep STUDY.yaml "
                         "--out DIR (nlos-cl sweep --example > study.yaml for a start)")
    log = (lambda *a: print(*a, file=sys.stderr)) if args.json else print
    try:
        result = sweep(args.study, args.out, workers=args.workers, scheduler=args.scheduler,
                          resume=args.resume, batch_size=args.batch_size,
                          progress=not args.no_progress, log=log,
                          allow_runner=args.allow_runner, force=args.force)
    except KeyboardInterrupt:
        print(f"\nsweep: interrupted; the finished batches are in {args.out}/runs.parquet. "
              f"Finish with: nlos-cl sweep {args.study} --out {args.out} --resume",
              file=sys.stderr)
        return 130
    _report(result, args.json)
    return 0


def _report(result, as_json: bool) -> None:
    done = result.n_runs - result.n_skipped
    info = {"out": str(result.out), "runs": result.n_runs, "ran": done,
            "skipped": result.n_skipped, "failed": result.n_failed, "workers": result.workers,
            "tasks": result.tasks, "wall_s": round(result.wall_s, 2),
            "summary": str(result.summary) if result.summary else None,
            "figures": result.figures}
    if as_json:
        print(json.dumps(info))
        return
    where = f"on {result.workers} worker(s)" if result.workers else "in this process"
    print(f"sweep: {done} runs in {result.wall_s:.1f} s {where}, "
          f"{result.tasks} tasks ({result.n_skipped} done before); {result.n_failed} failed")
    summary = f"   summary: {result.summary}" if result.summary else ""  # none: a runner's
    print(f"table: {result.out}/runs.parquet{summary}")
    for figure in result.figures:
        print(f"figure: {figure}")
    if result.n_failed:
        table = result.table()
        first = next(f for f in table.column("failure").to_pylist() if f)
        print(f"first failure: {first}")


def _parser():
    p = argparse.ArgumentParser(prog="nlos-cl sweep", description=__doc__.split("\n\n")[0])
    add_arguments(p)
    return p


if __name__ == "__main__":
    from nlos_cl.core.errors import DeviceError, InputError
    try:
        sys.exit(main(_parser().parse_args()))
    except (InputError, DeviceError) as exc:
        print(f"nlos-cl: {exc}", file=sys.stderr)
        sys.exit(2)
