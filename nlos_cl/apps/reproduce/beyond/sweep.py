"""`reproduce beyond` through the sweep engine: its cases (built by experiment.py from beyond.yaml)
become one runner study (runs.run: a case and a seed per run), nl.sweep runs it, and the
table turns back into the rows the report is made from.

The runs go in this process by default (Settings.workers = 0, like the paper's studies; a
LocalCluster with workers=None or N). The table stays in OUT/beyond_sweep/, started afresh
each time (an old one may come from older code).
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

from nlos_cl.core.errors import InputError

from ..common import Settings

RUNNER = "nlos_cl.apps.reproduce.beyond.runs:run"
SETTINGS = ("facet_m", "grid_step_m", "dt_s", "snr_db", "h_s")  # what a frame depends on
FOLDER = "beyond_sweep"


def frames(section: str, case: str, lay, targets, seeds: int, *, seed0: int = 0,
           z_range=None, k=1, photons=None, model_lay=None) -> dict:
    """One simulated scene's frames: the case as plain data (what the runner gets) and its
    seeds. `targets`: (size, position[, normal]) tuples; z_range: None for the plane z = 0."""
    case_data = {"section": section, "case": case, "layout": lay.name,
                 "targets": json.loads(json.dumps(targets)),  # tuples as lists: plain data
                 "z_range": None if z_range is None else list(z_range), "k": k,
                 "photons": photons, "model_layout": model_lay.name if model_lay else None}
    return {"case": case_data, "seeds": list(range(seed0, seed0 + seeds))}


def study(entries, cfg: dict, s: Settings) -> dict:
    """The runner study of every frame of `entries`, in their order: run i is the i-th
    (case, seed), zipped (cases have different seed counts)."""
    runs = [(f["case"], seed) for e in entries for f in e["frames"] for seed in f["seeds"]]
    return {"description": "reproduce beyond" + (" --quick" if s.quick else ""),
            "runner": RUNNER,
            "axes": [{"zip": [{"name": "case", "values": [c for c, _ in runs]},
                              {"name": "seed", "values": [seed for _, seed in runs]}]}],
            "params": {"layouts": cfg["layouts"],
                       "settings": {k: getattr(s, k) for k in SETTINGS}}}


def fill(entries, table) -> None:
    """Each entry's rows from the table (its runs, in run_id order, are the entries' frames in
    order); a note that is a function of the rows is computed now. A failed run is an error:
    the report must not silently drop frames (a model failure is a note, not a failed run)."""
    runs = table.to_pylist()
    failed = [r for r in runs if r["failure"]]
    if failed:
        raise InputError(f"reproduce beyond: {len(failed)} of {len(runs)} frame(s) failed, the "
                         f"first (run_id {failed[0]['run_id']}): {failed[0]['failure']}. "
                         "Fix: check beyond.yaml and the settings (--quick, --seeds)")
    results = iter(runs)
    for e in entries:
        e["rows"] = [row for f in e["frames"] for _ in f["seeds"]
                     for row in json.loads(next(results)["result"])]
        if callable(e["note"]):
            e["note"] = e["note"](e["rows"])


def run_entries(entries, cfg: dict, s: Settings, out: Path) -> None:
    """Run every frame of `entries` through nl.sweep and fill in their rows."""
    from nlos_cl.sweep import sweep
    if not entries:
        return
    folder = Path(out) / FOLDER
    if any((folder / f).exists() for f in ("study.json", "runs.parquet")):  # an earlier run's
        shutil.rmtree(folder)
    result = sweep(study(entries, cfg, s), folder, workers=s.workers, progress=False,
                   report=False, log=lambda _text: None)  # reproduce prints its own lines
    fill(entries, result.table())
