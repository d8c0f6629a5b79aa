"""Fig. 10: the target at every point of a 5 x 5 grid of positions; the error of each method
per position and over all positions and seeds, against the paper's.

Run as a parameter study through the sweep machinery (studies.py: the package file
nlos_cl/sweep/fig10.yaml with these Settings applied); OUT/fig10_sweep/ keeps the tidy table
of every run."""
from __future__ import annotations

from pathlib import Path

from nlos_cl.apps import plotting

from ..common import PAPER, Result, Settings, error_stats, title
from .studies import METHODS, run_study


def fig10(s: Settings, out: Path) -> Result:
    table = run_study("fig10", s, out)
    rows, errors = [], {m: [] for m in METHODS}
    for x in range(1, 6):
        for y in range(1, 6):
            row = {"x": x, "y": y}
            for m, how in METHODS.items():
                e = [r["error_m"] for r in table if (r["x"], r["y"], r["method"]) == (x, y, how)]
                errors[m].extend(e)
                st = error_stats(e)
                row.update({f"{m}_mean_m": st["mean_m"], f"{m}_max_m": st["max_m"]})
            rows.append(row)
    return fig10_result(rows, errors, out)


def fig10_result(rows, errors: dict, out: Path) -> Result:
    """The summary over all positions and seeds ({method: [error per run]}) and the figure."""
    summary = {m: error_stats(e) for m, e in errors.items()}
    summary["paper"] = PAPER["fig10"]
    figure = plotting.grid_errors_figure(rows, errors, summary, out, "fig10")
    return Result("fig10", title("fig10"), rows, summary, [figure])
