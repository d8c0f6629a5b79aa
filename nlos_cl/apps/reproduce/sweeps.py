"""The sweeps: one quantity varied, the error (or the located position) against it.
Fig. 7(a) detector spacing, Fig. 7(b) filter window, Table 1 laser FWHM, Fig. 9 target size."""
from __future__ import annotations

from pathlib import Path

from tqdm import tqdm

import nlos_cl as nl
from nlos_cl import plotting

from .common import (PAPER, Result, Settings, flat, paper_position_row, paper_target, run_trials,
                     stats, title)


def method_rows(key, values, scene_of, s: Settings, desc, methods=("filter", "fit")):
    """One row per value: {key: value, '<method>_mean_m': .., ...} over the noise seeds."""
    rows = []
    for value in tqdm(values, desc=desc, leave=False):
        trials, _ = run_trials(scene_of(value), s, methods=methods)
        row = {key: value}
        for m in methods:
            row.update(flat(m, stats(trials[m])))
        rows.append(row)
    return rows


def fig7a(s: Settings, out: Path) -> Result:
    deltas = [0.2, 0.6, 1.0] if s.quick else [round(0.1 * k, 1) for k in range(1, 11)]

    def scene_of(delta):
        setup = nl.paper_setup(detector_spots=[[-k * delta, 0.0, 0.0] for k in (1, 2, 3)])
        return paper_target(s=s, setup=setup)

    rows = method_rows("delta_m", deltas, scene_of, s, "fig7a: detector spacing")
    figure = plotting.sweep_figure(rows, "delta_m", "detector spacing delta (m)",
                                   "Fig. 7(a): error against detector spacing", out, "fig7a")
    return Result("fig7a", title("fig7a"), rows, {"rows": rows}, [figure])


def fig7b(s: Settings, out: Path) -> Result:
    hs = [0.1, 0.65, 1.5] if s.quick else [round(0.1 * k, 2) for k in range(1, 16)] + [0.65]
    hs = sorted(set(hs))
    trials, _ = run_trials(paper_target(s=s), s, methods=("filter",),
                           h_values=[h * 1e-9 for h in hs])
    rows = [{"h_ns": h, **flat("filter", stats(trials[("filter", h * 1e-9)]))} for h in hs]
    figure = plotting.sweep_figure(rows, "h_ns", "filter window h (ns)",
                                   "Fig. 7(b): error against filter window", out, "fig7b",
                                   ("filter",))
    return Result("fig7b", title("fig7b"), rows, {"rows": rows}, [figure])


def table1(s: Settings, out: Path) -> Result:
    rows = []
    for fwhm in tqdm(PAPER["table1"], desc="table1: laser FWHM", leave=False):
        setup = nl.paper_setup(pulse=nl.Pulse.from_laser(fwhm_s=fwhm * 1e-12))
        trials, _ = run_trials(paper_target(s=s, setup=setup), s, methods=("filter",))
        rows.append(paper_position_row("fwhm_ps", fwhm, stats(trials["filter"]),
                                       PAPER["table1"][fwhm]))
    return Result("table1", title("table1"), rows, {"rows": rows})


def fig9(s: Settings, out: Path) -> Result:
    sides = [0.2, 0.8, 1.6] if s.quick else [0.1, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.6, 2.0]
    rows = method_rows("side_m", sides,
                       lambda side: paper_target(width=side, height=side, s=s), s,
                       "fig9: square side")
    figure = plotting.sweep_figure(rows, "side_m", "side of the square target (m)",
                                   "Fig. 9: error against target size", out, "fig9")
    return Result("fig9", title("fig9"), rows, {"rows": rows}, [figure])
