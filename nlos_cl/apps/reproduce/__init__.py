"""`nlos-cl reproduce NAME`: every experiment of the paper as one command, writing its figure,
its table (CSV) and a summary with the paper's numbers beside ours.

Each experiment simulates its scenes once on the device, then for every noise seed runs the
device-resident pipeline (noise -> Gauss filter -> locate), the Gauss-fit baseline (a converged
SciPy fit per histogram, Eq. 25) and the raw signal, and reports mean +- std and max over seeds.

The paper's experiments are the subpackage `paper` (fig5, fig6, sweeps: fig7a/fig7b/table1/fig9,
fig8, fig10); what every experiment shares in `common`; the paper's report in `report`; the
paper's numbers in paper.yaml and our prose in text.yaml (data files of this package); every
figure in `nlos_cl.apps.plotting`. The sweeps and fig10 are study files
(nlos_cl/sweep/<name>.yaml) run through the sweep engine (`paper.studies`).

The other experiments are one subpackage each, with their own data files, and 'all' includes
none of them: `beyond` sets the paper's estimator against the model-based one and writes its own
report; `tracking` the tracker's tables of docs/tracking.md; `real` the measured datasets;
`draws` random draws (the draws themselves: nlos_cl.simulation.draws); `flood` a multizone
sensor's flood read as confocal; `scenarios` first-use scenes run through the command line with
no option.
"""
from __future__ import annotations

import inspect
import time
from pathlib import Path

from tqdm import tqdm

from ...core.errors import require
from . import beyond, draws, flood, real, scenarios, tracking
from .common import (PAPER, Result, Settings, fwhm_ns, paper_target, run_trials, stats,
                     write_csv)
from .paper import fig5, fig6, fig8, fig10, sweeps
from .report import summary_json, write_report

EXPERIMENTS = {"fig5": fig5.fig5, "fig6": fig6.fig6, "fig7a": sweeps.fig7a, "fig7b": sweeps.fig7b,
               "table1": sweeps.table1, "fig8": fig8.fig8, "fig9": sweeps.fig9,
               "fig10": fig10.fig10}
PAPER_EXPERIMENTS = tuple(EXPERIMENTS)  # what 'all' runs: the paper's experiments
EXPERIMENTS["beyond"] = beyond.beyond  # own report (docs/results/beyond/); not in 'all'
EXPERIMENTS["tracking"] = tracking.tracking  # docs/tracking.md's tables; not in 'all'
EXPERIMENTS["real"] = real.real  # the measured datasets (docs/results/real-data/); not in 'all'
EXPERIMENTS["draws"] = draws.draws  # random draws (docs/results/draws/draws.md); not in 'all'
EXPERIMENTS["flood"] = flood.flood  # the flood study (docs/results/flood/flood.md); not in 'all'
EXPERIMENTS["scenarios"] = scenarios.scenarios  # first-use scenes, CLI with no option; not in 'all'


def run(name: str, s: Settings, out: Path, **options) -> list[Result]:
    """Run one experiment (or 'all'), writing out/<name>.csv and its figures; `options` (only,
    cold) go to the experiment, which refuses those it does not take."""
    names = list(PAPER_EXPERIMENTS) if name == "all" else [name]
    for n in names:
        taken = inspect.signature(EXPERIMENTS[n]).parameters
        for option in options:
            require(option in taken, f"--{option}", f"is not an option of {n}",
                    "leave it out (beyond takes --only; tracking --only and --cold; draws "
                    "--only, --draws and --jobs; real --data; flood and scenarios --draws)")
    out.mkdir(parents=True, exist_ok=True)
    results = []
    for n in tqdm(names, desc="reproduce", disable=len(names) == 1):
        start = time.perf_counter()
        result = EXPERIMENTS[n](s, out, **options)
        result.seconds = time.perf_counter() - start
        write_csv(out / f"{n}.csv", result.rows)
        results.append(result)
    return results


__all__ = ["Settings", "Result", "run", "write_report", "summary_json", "fwhm_ns", "EXPERIMENTS",
           "PAPER", "PAPER_EXPERIMENTS", "paper_target", "run_trials", "stats"]
