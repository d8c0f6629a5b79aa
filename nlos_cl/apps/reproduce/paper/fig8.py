"""Fig. 8: rectangles of three shapes at (4, 2): their signals and located positions."""
from __future__ import annotations

from pathlib import Path

from nlos_cl.apps import plotting

from ..common import PAPER, Result, Settings, paper_position_row, paper_target, run_trials, stats, title

SHAPES = ((0.2, 1.8), (0.5, 1.5), (0.8, 1.2))  # width x height (m)


def fig8(s: Settings, out: Path) -> Result:
    rows, panels = [], []
    for w, h in SHAPES:
        label = f"{w}x{h}"
        trials, clean = run_trials(paper_target(width=w, height=h, s=s), s,
                                   methods=("filter", "fit"))
        st = stats(trials["filter"])
        row = paper_position_row("target_m", label, st, PAPER["fig8"][label],
                                 fit_error_mean_m=stats(trials["fit"])["mean_m"])
        rows.append(row)
        c = clean.histograms()
        t = c.time_axis.centres()
        sl = plotting.signal_window(c.data[0], t)
        panels.append((f"{w} m x {h} m: located ({st['x']:.2f}, {st['y']:.2f}), paper "
                       f"({row['paper_x']}, {row['paper_y']})", t[sl] * 1e9,
                       [(c.data[d, sl], "-", f"detector {n}") for d, n in enumerate("ABC")]))
    figure = plotting.signals_figure(panels, "Fig. 8: signals of three rectangles at (4, 2)",
                                     out, "fig8")
    return Result("fig8", title("fig8"), rows, {"rows": rows}, [figure])
