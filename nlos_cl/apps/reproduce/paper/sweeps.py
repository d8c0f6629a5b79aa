"""The sweeps: one quantity varied, the error (or the located position) against it.
Fig. 7(a) detector spacing, Fig. 7(b) filter window, Table 1 laser FWHM, Fig. 9 target size:
each a study file (nlos_cl/sweep/<name>.yaml) run through the sweep engine (studies.py)."""
from __future__ import annotations

from pathlib import Path

from nlos_cl.apps import plotting

from ..common import PAPER, Result, Settings, paper_position_row, title
from .studies import method_rows, run_study, stats


def fig7a(s: Settings, out: Path) -> Result:
    rows = method_rows(run_study("fig7a", s, out), "delta_m")
    figure = plotting.sweep_figure(rows, "delta_m", "detector spacing delta (m)",
                                   "Fig. 7(a): error against detector spacing", out, "fig7a")
    return Result("fig7a", title("fig7a"), rows, {"rows": rows}, [figure])


def fig7b(s: Settings, out: Path) -> Result:
    rows = method_rows(run_study("fig7b", s, out), "h_ns", ("filter",))
    figure = plotting.sweep_figure(rows, "h_ns", "filter window h (ns)",
                                   "Fig. 7(b): error against filter window", out, "fig7b",
                                   ("filter",))
    return Result("fig7b", title("fig7b"), rows, {"rows": rows}, [figure])


def table1(s: Settings, out: Path) -> Result:
    table = run_study("table1", s, out)
    rows = [paper_position_row("fwhm_ps", fwhm, stats([r for r in table if r["fwhm_ps"] == fwhm]),
                               PAPER["table1"][fwhm])
            for fwhm in dict.fromkeys(r["fwhm_ps"] for r in table)]
    return Result("table1", title("table1"), rows, {"rows": rows})


def fig9(s: Settings, out: Path) -> Result:
    rows = method_rows(run_study("fig9", s, out), "side_m")
    figure = plotting.sweep_figure(rows, "side_m", "side of the square target (m)",
                                   "Fig. 9: error against target size", out, "fig9")
    return Result("fig9", title("fig9"), rows, {"rows": rows}, [figure])
