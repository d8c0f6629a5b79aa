"""Proof that the paper's sweeps give the same outputs through the sweep engine as the classic
loops did (docs/sweeps.md, "The paper's sweeps on it").

For each figure (fig7a, fig7b, table1, fig9, fig10) it runs the classic loop (kept here, as it
was in nlos_cl/apps/reproduce before the study files: simulate once per scene, then per seed
noise -> filter/fit/raw -> locate) and `reproduce`'s sweep path (the study file through
nl.sweep, with the given --workers, 0 = in this process), alternating the order per repeat, and compares the
rows, the summary, the CSV (bytes) and the figure (bytes). Prints one JSON object.

    .venv/bin/python scripts/sweep_paper.py --quick --out /tmp/paper_check
    .venv/bin/python scripts/sweep_paper.py --figs fig7a,fig7b --workers 0,2 --out /tmp/full
"""
from __future__ import annotations

import argparse
import filecmp
import json
import statistics
import time
from dataclasses import replace
from pathlib import Path

import nlos_cl as nl
from nlos_cl.apps import plotting
from nlos_cl.apps import reproduce as rp
from nlos_cl.apps.reproduce import _write_csv  # reproduce's own CSV writer
from nlos_cl.apps.reproduce.common import METHODS, PAPER, Result, flat, paper_position_row, paper_target, run_trials, stats, title
from nlos_cl.apps.reproduce.fig10 import fig10_result


def _method_rows(key, values, scene_of, s, methods=("filter", "fit")):
    rows = []
    for value in values:
        trials, _ = run_trials(scene_of(value), s, methods=methods)
        row = {key: value}
        for m in methods:
            row.update(flat(m, stats(trials[m])))
        rows.append(row)
    return rows


def classic_fig7a(s, out):
    deltas = [0.2, 0.6, 1.0] if s.quick else [round(0.1 * k, 1) for k in range(1, 11)]

    def scene_of(delta):
        setup = nl.paper_setup(detector_spots=[[-k * delta, 0.0, 0.0] for k in (1, 2, 3)])
        return paper_target(s=s, setup=setup)
    rows = _method_rows("delta_m", deltas, scene_of, s)
    figure = plotting.sweep_figure(rows, "delta_m", "detector spacing delta (m)",
                                   "Fig. 7(a): error against detector spacing", out, "fig7a")
    return Result("fig7a", title("fig7a"), rows, {"rows": rows}, [figure])


def classic_fig7b(s, out):
    hs = [0.1, 0.65, 1.5] if s.quick else [round(0.1 * k, 2) for k in range(1, 16)] + [0.65]
    hs = sorted(set(hs))
    trials, _ = run_trials(paper_target(s=s), s, methods=("filter",),
                           h_values=[h * 1e-9 for h in hs])
    rows = [{"h_ns": h, **flat("filter", stats(trials[("filter", h * 1e-9)]))} for h in hs]
    figure = plotting.sweep_figure(rows, "h_ns", "filter window h (ns)",
                                   "Fig. 7(b): error against filter window", out, "fig7b",
                                   ("filter",))
    return Result("fig7b", title("fig7b"), rows, {"rows": rows}, [figure])


def classic_fig9(s, out):
    sides = [0.2, 0.8, 1.6] if s.quick else [0.1, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.6, 2.0]
    rows = _method_rows("side_m", sides, lambda side: paper_target(width=side, height=side, s=s),
                        s)
    figure = plotting.sweep_figure(rows, "side_m", "side of the square target (m)",
                                   "Fig. 9: error against target size", out, "fig9")
    return Result("fig9", title("fig9"), rows, {"rows": rows}, [figure])


def classic_fig10(s, out):
    rows, errors = [], {m: [] for m in METHODS}
    for x, y in [(x, y) for x in range(1, 6) for y in range(1, 6)]:
        trials, _ = run_trials(paper_target((float(x), float(y), 0.0), s=s), s)
        row = {"x": x, "y": y}
        for m in METHODS:
            st = stats(trials[m])
            errors[m].extend(loc.error_m for loc in trials[m])
            row.update({f"{m}_mean_m": st["mean_m"], f"{m}_max_m": st["max_m"]})
        rows.append(row)
    return fig10_result(rows, errors, out)  # the summary and figure code reproduce uses


def classic_table1(s, out):
    rows = []
    for fwhm in PAPER["table1"]:
        setup = nl.paper_setup(pulse=nl.Pulse.from_laser(fwhm_s=fwhm * 1e-12))
        trials, _ = run_trials(paper_target(s=s, setup=setup), s, methods=("filter",))
        rows.append(paper_position_row("fwhm_ps", fwhm, stats(trials["filter"]),
                                       PAPER["table1"][fwhm]))
    return Result("table1", title("table1"), rows, {"rows": rows})


CLASSIC = {"fig7a": classic_fig7a, "fig7b": classic_fig7b, "table1": classic_table1,
           "fig9": classic_fig9, "fig10": classic_fig10}


def _timed(fn, s, out: Path):
    """(result, wall s, CPU s of this process): on a shared machine the CPU time is the fairer
    measure of the work (the in-process ways only: Dask workers are other processes)."""
    out.mkdir(parents=True, exist_ok=True)
    start, cpu = time.perf_counter(), time.process_time()
    result = fn(s, out)
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    _write_csv(out / f"{result.name}.csv", result.rows)
    return result, seconds, cpu


def _same(a, b, out_a: Path, out_b: Path) -> dict:
    name = a.name
    return {"rows": a.rows == b.rows, "summary": a.summary == b.summary,
            "csv": filecmp.cmp(out_a / f"{name}.csv", out_b / f"{name}.csv", shallow=False),
            "png": all(filecmp.cmp(out_a / f, out_b / f, shallow=False) for f in a.figures)}


def check(name: str, s, workers: list[int], repeat: int, out: Path) -> dict:
    times = {"classic": []} | {f"sweep_w{w}": [] for w in workers}
    cpu = {way: [] for way in times}
    verdicts = {}
    for k in range(repeat):
        order = list(times) if k % 2 == 0 else list(times)[::-1]  # alternate: load drifts
        results = {}
        for way in order:
            folder = out / f"{name}-{way}-{k}"
            if way == "classic":
                results[way], sec, cpu_s = _timed(CLASSIC[name], s, folder)
            else:
                ws = replace(s, workers=int(way.removeprefix("sweep_w")))
                results[way], sec, cpu_s = _timed(rp.EXPERIMENTS[name], ws, folder)
            times[way].append(round(sec, 2))
            cpu[way].append(round(cpu_s, 2))
        for way in results:
            if way != "classic":
                verdicts.setdefault(way, []).append(_same(
                    results["classic"], results[way], out / f"{name}-classic-{k}",
                    out / f"{name}-{way}-{k}"))
    return {"times_s": times, "median_s": {w: statistics.median(t) for w, t in times.items()},
            "cpu_s": cpu, "median_cpu_s": {w: statistics.median(t) for w, t in cpu.items()},
            "identical": {w: {key: all(v[key] for v in vs) for key in vs[0]}
                          for w, vs in verdicts.items()}}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--figs", default="fig7a,fig7b,table1,fig9,fig10")
    p.add_argument("--workers", default="0", help="sweep engine workers to try, e.g. 0,2")
    p.add_argument("--repeat", type=int, default=1)
    p.add_argument("--out", required=True)
    args = p.parse_args()
    s = rp.Settings.make(quick=args.quick)
    workers = [int(w) for w in args.workers.split(",")]
    report = {"quick": args.quick, "settings": s.describe()}
    for name in args.figs.split(","):
        report[name] = check(name, s, workers, args.repeat, Path(args.out))
        print(name, json.dumps(report[name]), flush=True)
    print(json.dumps(report))


if __name__ == "__main__":
    main()
