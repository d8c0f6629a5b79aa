"""The paper's sweeps as study files (nlos_cl/sweep/fig7a.yaml, fig7b.yaml, table1.yaml,
fig9.yaml, fig10.yaml), run through nl.sweep and turned back into reproduce's rows.

A study file holds the full setting; reproduce's Settings replace its facet size, time bins,
SNR, seeds, filter window and grid step, and --quick keeps three values of the swept axis.
The runs go through the sweep engine in this process (workers=0): these studies take seconds,
less than starting a Dask cluster costs (docs/sweeps.md has both measured); `nlos-cl sweep
nlos_cl/sweep/fig10.yaml --out DIR` runs the same file on any cluster. The table stays in
OUT/<name>_sweep/.
"""
from __future__ import annotations

import shutil
from importlib import resources
from pathlib import Path

import numpy as np

from ..common import Settings, error_stats, flat

METHODS = {"filter": "gauss", "fit": "gauss_fit", "raw": "none"}  # ours -> the study's filter
QUICK = {"fig7a": ("delta_m", (0.2, 0.6, 1.0)), "fig7b": ("h_ns", (0.1, 0.65, 1.5)),
         "fig9": ("side_m", (0.2, 0.8, 1.6))}  # --quick: these values of the swept axis


def study(name: str, s: Settings) -> dict:
    """nlos_cl/sweep/<name>.yaml with reproduce's Settings applied."""
    import yaml

    from nlos_cl.io.scenefile import yaml_loader
    text = resources.files("nlos_cl.sweep").joinpath(f"{name}.yaml").read_text("utf-8")
    spec = yaml.load(text, Loader=yaml_loader())
    scene = spec["scene"]
    scene["facet_size_m"] = s.facet_m
    scene["time_axis"]["dt_s"] = s.dt_s
    scene["noise"]["snr_db"] = s.snr_db
    spec.update(seeds=s.seeds, h_s=s.h_s)
    spec["grid"]["step_m"] = s.grid_step_m
    if s.quick and name in QUICK:
        axis, keep = QUICK[name]
        for a in spec["axes"]:
            if a.get("name") == axis:
                a["values"] = [v for v in a["values"] if v in keep]
    return spec


def run_study(name: str, s: Settings, out: Path) -> list[dict]:
    """The study's table as rows (dicts in run_id order). It starts afresh in OUT/<name>_sweep/
    (the classic loops recomputed every time; an old table may come from older code). A failed
    run is an error here, as it was in the loops: a figure must not silently drop runs."""
    from nlos_cl.core.errors import InputError
    from nlos_cl.sweep import sweep
    folder = Path(out) / f"{name}_sweep"
    if any((folder / f).exists() for f in ("study.json", "runs.parquet")):  # an earlier run's
        shutil.rmtree(folder)
    result = sweep(study(name, s), folder, workers=s.workers, progress=False, report=False,
                   log=_quiet)
    rows = result.table().to_pylist()
    failed = [r for r in rows if r["failure"]]
    if failed:
        raise InputError(f"reproduce {name}: {len(failed)} run(s) failed (table in {folder}), "
                         f"the first (run_id {failed[0]['run_id']}): {failed[0]['failure']}. "
                         "Fix: check the settings (--quick, --seeds)")
    return rows


def _quiet(_text: str) -> None:
    """reproduce prints its own progress; the engine's status line is not news here."""


def stats(rows) -> dict:
    """common.stats over table rows: error mean/std/max over seeds, mean located (x, y)."""
    pos = np.mean([[r["x_m"], r["y_m"]] for r in rows], axis=0)
    return {**error_stats([r["error_m"] for r in rows]),
            "x": round(float(pos[0]), 3), "y": round(float(pos[1]), 3)}


def method_rows(table, key: str, methods=("filter", "fit")) -> list[dict]:
    """One row per value of `key` (study order): {key: value, '<method>_mean_m': .., ...}."""
    rows = []
    for value in dict.fromkeys(r[key] for r in table):
        row = {key: value}
        for m in methods:
            runs = [r for r in table
                    if r[key] == value and r.get("method", METHODS["filter"]) == METHODS[m]]
            row.update(flat(m, stats(runs)))
        rows.append(row)
    return rows
