"""Fig. 10: the target at every point of a 5 x 5 grid of positions; the error of each method
per position and over all positions and seeds, against the paper's."""
from __future__ import annotations

from pathlib import Path

from tqdm import tqdm

from nlos_cl import plotting

from .common import (METHODS, PAPER, Result, Settings, error_stats, paper_target, run_trials,
                     stats, title)

COORDS = [(x, y) for x in range(1, 6) for y in range(1, 6)]  # metres


def fig10(s: Settings, out: Path) -> Result:
    rows = []
    errors = {m: [] for m in METHODS}
    for x, y in tqdm(COORDS, desc="fig10: 5 x 5 positions", leave=False):
        trials, _ = run_trials(paper_target((float(x), float(y), 0.0), s=s), s)
        row = {"x": x, "y": y}
        for m in METHODS:
            st = stats(trials[m])
            errors[m].extend(loc.error_m for loc in trials[m])
            row.update({f"{m}_mean_m": st["mean_m"], f"{m}_max_m": st["max_m"]})
        rows.append(row)
    summary = {m: error_stats(errors[m]) for m in METHODS}
    summary["paper"] = PAPER["fig10"]
    figure = plotting.grid_errors_figure(rows, errors, summary, out, "fig10")
    return Result("fig10", title("fig10"), rows, summary, [figure])
