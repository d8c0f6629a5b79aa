"""Time a >= 2,000-run study with 1 and with 2 local workers (issue 15): wall times, speed-up,
per-task overhead against the time spent inside runs, bit-identical tables.

    .venv/bin/python scripts/sweep_bench.py [--study docs/sweeps/bench_2000.yaml]
        [--out out/sweep_bench] [--workers 2 1] [--plots docs/sweeps] [--seeds N]

Each local worker gets cores / workers PoCL threads (POCL_CPU_MAX_CU_NUM) unless the variable
is set: POCL_CPU_MAX_CU_NUM=1 gives every worker one thread, so 1 vs 2 measures processes alone.

Writes OUT/w<N>/ per worker count and prints one JSON object (docs/sweeps.md quotes it).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
from pathlib import Path

import numpy as np


def measure(study, out: Path, workers: int) -> dict:
    from nlos_cl.sweep import sweep
    shutil.rmtree(out, ignore_errors=True)
    result = sweep(study, out, workers=workers)
    table = result.table()
    inside = float(np.sum(table.column("t_run_s").to_numpy()))
    cpu = float(np.sum(table.column("t_cpu_s").to_numpy())) if "t_cpu_s" in table.column_names \
        else float("nan")
    kernel = float(sum(np.sum(table.column(c).to_numpy())
                       for c in ("t_simulate_s", "t_noise_s", "t_filter_s", "t_locate_s")))
    # worker time not spent inside a run: scheduling, (de)serialising, idle at the end
    overhead = workers * result.run_s - inside
    return {"workers": workers, "runs": result.n_runs, "tasks": result.tasks,
            "failed": result.n_failed, "wall_s": round(result.wall_s, 1),
            "run_s": round(result.run_s, 1), "inside_runs_s": round(inside, 1),
            "stages_s": round(kernel, 1), "cpu_in_runs_s": round(cpu, 1),
            "overhead_per_task_ms": round(1e3 * overhead / max(result.tasks, 1), 1),
            "mean_run_ms": round(1e3 * inside / result.n_runs, 1),
            "mean_task_s": round(inside / max(result.tasks, 1), 2)}


def identical(a: Path, b: Path) -> bool:
    from nlos_cl.sweep import read_table
    from nlos_cl.sweep.runs import TIMING_COLUMNS
    ta, tb = read_table(a), read_table(b)
    for name in ta.column_names:
        if name in TIMING_COLUMNS:
            continue
        x, y = ta.column(name), tb.column(name)
        if x.type.id in (11, 12):  # float32 / float64: compare bits (NaN == NaN)
            if not np.array_equal(x.to_numpy().view(np.int64), y.to_numpy().view(np.int64)):
                return False
        elif x.to_pylist() != y.to_pylist():
            return False
    return ta.num_rows == tb.num_rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--study", default="docs/sweeps/bench_2000.yaml")
    p.add_argument("--out", default="out/sweep_bench")
    p.add_argument("--workers", type=int, nargs="+", default=[2, 1])
    p.add_argument("--plots", default="", help="copy the summary plots here")
    p.add_argument("--seeds", type=int, default=None, help="override the study's seeds (fewer runs)")
    args = p.parse_args()
    out = Path(args.out)
    study = args.study
    if args.seeds:
        from nlos_cl.sweep import load_study
        raw = load_study(args.study).as_dict()
        study = {**raw, "seeds": args.seeds}
    rows = [measure(study, out / f"w{n}", n) for n in args.workers]
    report = {"study": args.study, "seeds": args.seeds,
              "POCL_CPU_MAX_CU_NUM": os.environ.get("POCL_CPU_MAX_CU_NUM", "cores / workers"),
              "measured": rows}
    by = {r["workers"]: r for r in rows}
    if 1 in by and 2 in by:
        report["speed_up_2_vs_1"] = round(by[1]["run_s"] / by[2]["run_s"], 2)
        report["speed_up_wall_2_vs_1"] = round(by[1]["wall_s"] / by[2]["wall_s"], 2)
        report["bit_identical_1_vs_2"] = identical(out / "w1", out / "w2")
    if args.plots:
        for name in ("errors_by_axis.png", "error_map.png", "summary.csv"):
            src = out / f"w{args.workers[0]}" / name
            if src.exists():
                shutil.copy(src, Path(args.plots) / f"bench_2000_{name}")
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
