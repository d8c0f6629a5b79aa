"""Fig. 8: rectangles of three shapes at (4, 2): their signals and located positions."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from nlos_cl.apps import plotting

from ..common import (PAPER, Result, Settings, paper_position_row, paper_target, run_trials,
                      simulate_clean, stats, title)

SHAPES = ((0.2, 1.8), (0.5, 1.5), (0.8, 1.2))  # width x height (m)


def fig8(s: Settings, out: Path) -> Result:
    rows, cleans = [], []
    for w, h in SHAPES:
        label = f"{w}x{h}"
        trials, clean = run_trials(paper_target(width=w, height=h, s=s), s,
                                   methods=("filter", "fit"))
        st = stats(trials["filter"])
        rows.append(paper_position_row("target_m", label, st, PAPER["fig8"][label],
                                       fit_error_mean_m=stats(trials["fit"])["mean_m"]))
        cleans.append(clean)
    return Result("fig8", title("fig8"), rows, {"rows": rows}, [figure(rows, cleans, out)])


def figure(rows, cleans, out: Path) -> str:
    """Every detector's clean signal per shape, in one window that holds them all (the signals
    arrive one after another: a window around the first detector's cut the others off), with
    the located and the paper's positions (rows: fig8's, or fig8.csv's)."""
    panels = []
    for (w, h), row, clean in zip(SHAPES, rows, cleans):
        c = clean.histograms()
        t = c.time_axis.centres()
        sl = plotting.signal_window(np.abs(c.data).max(axis=0), t)
        panels.append((f"{w} m x {h} m: located ({float(row['x']):.2f}, {float(row['y']):.2f}), "
                       f"paper ({row['paper_x']}, {row['paper_y']})", t[sl] * 1e9,
                       [(c.data[d, sl], "-", f"detector {plotting.DETECTOR_NAMES[d % 26]}")
                        for d in range(c.n_detectors)]))
    return plotting.signals_figure(panels, "Fig. 8: signals of three rectangles at (4, 2)", out,
                                   "fig8")


def redraw(s: Settings, out: Path, csv_path: Path) -> str:
    """fig8.png again from a run's fig8.csv (the located positions) and the clean signals
    (seconds; the noise trials and Gauss fits are what take the run's minutes)."""
    import csv
    with open(csv_path, newline="") as f:
        rows = list(csv.DictReader(f))
    cleans = [simulate_clean(paper_target(width=w, height=h, s=s), s) for w, h in SHAPES]
    return figure(rows, cleans, out)
