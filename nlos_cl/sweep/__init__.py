"""Parameter sweeps as Dask tasks (docs/sweeps.md): a study file (a base scene, axes, seeds,
estimators) becomes thousands of simulate -> noise -> filter -> locate runs, batched into Dask
tasks on a LocalCluster or any dask.distributed cluster, written as a Parquet table one batch at
a time (resumable), then summarised and plotted.

    import nlos_cl as nl
    result = nl.sweep("study.yaml", "out/study", workers=2)    # or scheduler="tcp://host:8786"
    table = result.table()                                      # a pyarrow.Table, one row per run

`nlos_cl.sweep` is both this package and the function: calling the module calls `sweep`, and
the function carries `load_study`, `read_table`, `example_text` and `worker_cache`, so
`nl.sweep(...)` and `nl.sweep.read_table(...)` work whichever of the two an import left under
that name.

A study may instead name a `runner`, a function whose axes are its keyword parameters and
whose return values the table keeps as JSON (runner.py; `worker_cache` keeps a worker's
expensive part, e.g. a clean simulation, for the runs that share it). A study with a runner is
a program: only nlos_cl's own functions run unless the user allows a module
(`nl.sweep(..., allow_runner=["mypackage"])`, `nlos-cl sweep --allow-runner mypackage`).

Modules: study (the file format, the runs), runner (studies of a function), runs (what a worker
does), engine (Dask, writing, progress), results (the Parquet table, the summary), plots. Dask
and pyarrow load only when a study runs or a table is read.
"""
from __future__ import annotations

import sys
import types
from importlib import resources

from .load import load_study
from .runner import RunnerStudy, worker_cache
from .study import Study


def sweep(study, out, **options):
    """Run a study; see nlos_cl.sweep.engine.sweep for the options (workers, scheduler,
    resume, batch_size, progress, report). Returns a SweepResult."""
    from .engine import sweep as run
    return run(study, out, **options)


def read_table(out):
    """A study's table (OUT or OUT/runs.parquet) as one pyarrow.Table sorted by run_id."""
    from .results import read_table as read
    return read(out)


def example_text() -> str:
    """A small runnable study (`nlos-cl sweep --example`)."""
    return resources.files(__package__).joinpath("example.yaml").read_text("utf-8")


sweep.load_study, sweep.read_table, sweep.example_text = load_study, read_table, example_text
sweep.worker_cache = worker_cache


class _CallableModule(types.ModuleType):
    def __call__(self, *args, **kwargs):
        return sweep(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule

__all__ = [
    "RunnerStudy",
    "Study",
    "example_text",
    "load_study",
    "read_table",
    "sweep",
    "worker_cache",
]
