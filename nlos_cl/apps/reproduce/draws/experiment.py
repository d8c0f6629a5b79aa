"""`nlos-cl reproduce draws`: evaluation by random draws, not chosen cases. Each
family (simulation/draws/draws.yaml: one, multi, closed, mismatch, crossings, counts) draws its
scenes at random (simulation.draws.families: a pure function of family, index and master seed),
simulates each with nlos_cl's forward model, adds noise, and locates it with the paper's argmax
and with the library's default estimator (run); crossings are sequences of two targets whose
paths cross, tracked as `nlos-cl track` tracks them (cross_run). The tables and the
targets checked come from the rows alone (report; cross_report for crossings).

Writes OUT/draws.csv (every row, by `reproduce.run`), OUT/draws-summary.csv and OUT/draws.md
(with --doc, that page there instead: docs/results/draws/draws.md). Not part of `reproduce all`;
--quick draws draws.yaml's quick_draws per family, `draws=N` (the CLI's --draws) N per family.

Re-run one draw alone: `rerun("one", 17)` (the family and index of its row; master_seed
defaults to draws.yaml's)."""
from __future__ import annotations

import math
import os
import time
import warnings
from pathlib import Path

from tqdm import tqdm

import nlos_cl as nl
from nlos_cl.core.errors import require

from ....simulation.draws import families
from ..common import Result, Settings, write_csv
from . import cross_report as cross, report

NAME = "draws"
TITLE = "Random draws: the paper's argmax and the default estimator on scenes nobody chose"


def _families(only) -> list[str]:
    if only is None:
        return list(families.FAMILIES)
    bad = [n for n in only if n not in families.FAMILIES]
    require(not bad, "--only", f"unknown family {bad[:1]}",
            f"use some of {list(families.FAMILIES)}")
    return [n for n in families.FAMILIES if n in only]


def _run_one(job) -> list[dict]:
    """One draw's rows (a worker process's task: everything it needs is in `job`)."""
    from . import run  # nlos_cl's estimators and SciPy: only when draws run
    family, index, master_seed, cfg, s = job
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # each row keeps its own warnings
        return run.run(families.draw(family, index, master_seed, cfg), s)


def run_rows(names, count: int, s: Settings, master_seed: int, cfg, jobs: int = 1
             ) -> list[dict]:
    """Every draw's rows, in (family, index) order whatever `jobs`: with jobs > 1 the draws
    run in that many spawned processes (each its own OpenCL context; a draw is a pure function
    of its job, so the rows are those of one process, times aside)."""
    tasks = [(f, i, master_seed, cfg, s) for f in names for i in range(count)]
    bar = dict(desc=NAME, total=len(tasks), disable=len(tasks) < 2)
    if jobs <= 1:
        return [r for t in tqdm(tasks, **bar) for r in _run_one(t)]
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    saved = {k: os.environ.get(k) for k in BLAS_THREADS}
    os.environ.update(dict.fromkeys(BLAS_THREADS, "1"))  # inherited by the spawned workers
    pool = ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("spawn"))
    try:
        return [r for rows in tqdm(pool.map(_run_one, tasks), **bar) for r in rows]
    except BaseException:  # a failed draw (or ^C): do not wait for the others first
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    finally:
        pool.shutdown()
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


# A worker's BLAS on one thread: `jobs` workers share the cores (read when NumPy loads, so
# set in the parent's environment, which the spawned workers start with)
BLAS_THREADS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def draws(s: Settings, out: Path, only=None, draws: int | None = None,
          master_seed: int | None = None, jobs: int | None = None) -> Result:
    """Draw `draws` scenes per family (default draws.yaml's; --quick: quick_draws), run them
    all (in `jobs` processes: --jobs), write the summary CSV and the page OUT/draws.md."""
    cfg = families.config()
    count = draws or (cfg["quick_draws"] if s.quick else cfg["draws"])
    require(isinstance(count, int) and count >= 1, "--draws", f"must be a positive whole "
            f"number, got {count!r}", "pass e.g. --draws 200")
    seed = cfg["master_seed"] if master_seed is None else int(master_seed)
    names = _families(only)
    start = time.perf_counter()
    require(jobs is None or (isinstance(jobs, int) and jobs >= 1), "--jobs", f"must be a "
            f"positive whole number, got {jobs!r}", "pass e.g. --jobs 2 (one per core)")
    rows = run_rows(names, count, s, seed, cfg, jobs or 1)
    seconds = time.perf_counter() - start
    located = [r for r in rows if r["family"] != cross.FAMILY]
    summ = report.summary(located, cfg["failure_m"]) + cross.summary(rows)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / f"{NAME}-summary.csv", uniform(summ))
    options = (" --quick" if s.quick else "") + (f" --draws {draws}" if draws else "") + (
        " --only " + " ".join(names) if only is not None else "") + (
        f" --jobs {jobs}" if jobs and jobs > 1 else "")
    text = page(rows, summ, cfg, made_by(s, options, seconds, seed))
    goals = report.goals(summ) + cross.goals(summ)
    from ....io.safe_write import write_text
    write_text(out / f"{NAME}.md", text, what="--out")
    # an infinite error (a missed target) is null in --json, which has no infinity
    finite = [{k: (None if isinstance(v, float) and not math.isfinite(v) else v)
               for k, v in r.items()} for r in summ]
    return Result(NAME, TITLE, uniform(rows), {"summary": finite, "goals": goals,
                                      "markdown": text, "draws_per_family": count,
                                      "master_seed": seed})


def uniform(rows) -> list[dict]:
    """Rows with every column any of them has (in first-seen order; blank where a family has
    none): a crossing row and a located one share draws.csv, whose header is the first row's."""
    columns = list(dict.fromkeys(k for r in rows for k in r))
    return [{k: r.get(k, "") for k in columns} for r in rows]


def made_by(s: Settings, options: str, seconds: float, seed: int) -> str:
    """The page's 'Generated by' sentence: the command, machine, time and settings."""
    return (f"Generated by `nlos-cl reproduce draws{options}` on {nl.resolve_backend().name}, "
            f"{os.cpu_count()} CPU cores, in {seconds / 60:.1f} min; master seed {seed}, facets "
            f"{s.facet_m * 100:g} cm, bins {s.dt_s * 1e12:g} ps")


def page(rows, summ, cfg, made: str, csv_name: str = "draws.csv") -> str:
    """The page, from the rows only: the sections of the families that ran; `made`: how the
    rows were made (made_by, or rerender's account of a committed CSV)."""
    fail = cfg["failure_m"]
    header = (f"# {TITLE}\n\n{made}; the ranges: nlos_cl/simulation/draws/draws.yaml. Every "
              f"row is in {csv_name} beside this page. Do not edit by hand.")
    how = ("Each draw is a pure function of (family, index, master seed): "
           "`nlos_cl.apps.reproduce.draws.rerun(family, index)` re-runs one alone. Both "
           "estimators run as `nl.locate_capture` runs them by default (the derived search "
           "region, the automatic log mode); 'paper' is `estimator='paper'`, 'default' no "
           "estimator given (multi: 'default K' told the number of targets, 'default auto' "
           "`targets='auto'`). The error is the 3-D distance from each truth's centre to the "
           "found target assigned to it (linear assignment), the worst of a draw's targets; a "
           f"target not found counts as an infinite error. A failure is an error above {fail:g} "
           "m; 'without a warning' counts failures whose answer carried no warning (the "
           "collinear layouts' notice that z (a vertical line: x) is unobservable is not "
           "counted: it is said for "
           "every answer; nor, where the truth is a plate, the notice that the spots cannot "
           "see a closed object's depth). Times are per call, on shared cores: noisy (with "
           "--jobs N, N draws share the cores: inflated).")
    located = [r for r in rows if r["family"] != cross.FAMILY]
    if any(r["family"] == "counts" for r in rows):
        c = cfg["families"]["counts"]
        how += (" A counts draw is a `one` scene whose frame is photon counts "
                "(`nl.PhotonCounter`, simulation.draws.scenes.photon_counts): mean signal photons per "
                f"detector {c['signal_photons'][0]:g}-{c['signal_photons'][1]:g} and dark + "
                f"ambient {c['ambient_rate_hz'][0]:g}-{c['ambient_rate_hz'][1]:g} Hz "
                f"(log-uniform), TDC bins {c['tdc_ps'][0]}-{c['tdc_ps'][1]} ps, jitter 30 ps; "
                "its row's 'counting' column holds these, its SNR is not used; both "
                "estimators read the counts as counts (Poisson).")
    # the targets' checks stay in --json's "goals" (for the session's note), not on the page
    sections = [header, how]
    if located:
        sections += ["## Per family and estimator",
                     report.summary_table([r for r in summ if r["family"] != cross.FAMILY]),
                     "## By layout", report.breakdown_table(located, fail, "layout"),
                     "## By shape", report.breakdown_table(located, fail, "shapes"),
                     "## Worst draws", report.worst_table(located)]
    if len(located) < len(rows):
        sections += ["## Crossings (tracked sequences)",
                     cross.how(cfg["families"][cross.FAMILY], fail), cross.summary_table(
                         [r for r in summ if r["family"] == cross.FAMILY]),
                     "### Draws that lost an id", cross.lost_table(rows)]
    return "\n\n".join(sections) + "\n"


def write_doc(result: Result, path: Path) -> None:
    """The run's page at `path` (--doc: docs/results/draws/draws.md), atomically and never through a
    link. Whether the page may be replaced (nlos_cl's, or --force) was checked before the run
    (reproduce_cmd._check_outputs), as for tracking's page."""
    from ....io.safe_write import write_text
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, result.summary["markdown"], what="--doc", keep_unless=lambda _: True)


def rerun(family: str, index: int, master_seed: int | None = None, s: Settings | None = None
          ) -> list[dict]:
    """One draw alone, as the full run ran it: its rows."""
    from . import run
    d = families.draw(family, index, master_seed)
    return run.run(d, s or Settings())
