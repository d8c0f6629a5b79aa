"""The study on Dask: batches of runs as tasks, results written as they finish.

By default a LocalCluster of worker processes (one thread each, one OpenCL runtime each) sized
to the machine; with `scheduler` an existing cluster (a `tcp://HOST:PORT` address or a
scheduler file). The client (this process) writes the table, so workers need no shared disk.
"""
from __future__ import annotations

import json
import logging
import math
import os
import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from ..core.errors import InputError, require
from ..core.limits import MAX_STUDY_RUNS, require_count
from . import results
from .folder_lock import folder_lock
from .load import load_study
from .runner import RunnerStudy
from .runs import run_batch, worker_info
from .study import SPECIAL, Study, check_scenes

STUDY_FILE = results.STUDY_FILE


@dataclass
class SweepResult:
    """Where a study's results are, and how its run went."""

    out: Path
    n_runs: int
    n_skipped: int  # done before (resume)
    n_failed: int
    wall_s: float
    workers: int  # 0: ran in this process (workers=0), no Dask
    tasks: int
    run_s: float = 0.0  # first task submitted to last result written (cluster start excluded)
    summary: Path | None = None
    figures: list = field(default_factory=list)

    def table(self):
        """The whole table (pyarrow.Table, sorted by run_id)."""
        return results.read_table(self.out)


def sweep(study, out, *, workers: int | None = None, scheduler: str | None = None,
          resume: bool = False, batch_size: int | None = None, progress: bool = True,
          report: bool = True, log=None, allow_runner=(), force: bool = False) -> SweepResult:
    """Run every run of `study` (a study file, dict or Study) not yet in OUT/runs.parquet, on
    `workers` local processes (default: one per core; 0: in this process, no Dask, for studies
    too small to pay for a cluster's start-up) or on the cluster at `scheduler`; then
    write OUT/summary.csv and the plots (report=True). Status lines go to `log` (default:
    stderr, so a --json on stdout stays parseable). `allow_runner`: modules (besides nlos_cl's)
    whose functions a study file's `runner` may name; a runner is code the study runs
    (runner.resolve). `force`: replace files in OUT that no sweep wrote (summary.csv...)."""
    log = log or _to_stderr
    study = load_study(study, allow_runner=allow_runner)
    require_count("study", study.n_runs, MAX_STUDY_RUNS, "runs (the axes' values, estimators "
                  "and seeds crossed)", "split the study, or take fewer values on an axis")
    with folder_lock(Path(out)):  # one sweep writes a folder; --resume reads it under the lock
        return _locked(study, Path(out), workers, scheduler, resume, batch_size, progress,
                       report, log, force)


def _locked(study, out: Path, workers, scheduler, resume, batch_size, progress, report, log,
            force) -> SweepResult:
    """sweep(), holding OUT's lock."""
    done = _prepare(out, study, resume, force)
    if not isinstance(study, RunnerStudy):  # a runner was checked when the study was loaded
        check_scenes(study)
    pending = [(rid, v) for rid, v in study.runs() if rid not in done]
    start = time.perf_counter()
    n_workers, n_tasks, run_s = 0, 0, 0.0
    if pending and workers == 0 and scheduler is None:  # in this process, no Dask
        log(f"sweep: in this process (workers=0), device {worker_info()['device']}")
        batches = make_batches(study, pending, batch_size or study.batch_size, 1)
        n_tasks, run_start = len(batches), time.perf_counter()
        plan = study.plan()
        _write_all(study, out, batches, (run_batch(plan, b) for b in batches), len(done),
                   progress)
        run_s = time.perf_counter() - run_start
    elif pending:
        with open_client(workers, scheduler, log) as client:
            n_workers = len(client.scheduler_info(n_workers=-1)["workers"])
            batches = make_batches(study, pending, batch_size or study.batch_size, n_workers)
            n_tasks = len(batches)
            run_start = time.perf_counter()
            _run(client, study, out, batches, len(done), progress)
            run_s = time.perf_counter() - run_start
    wall = time.perf_counter() - start
    table = results.read_table(out)
    failed = 0 if table is None else sum(1 for f in table.column("failure").to_pylist() if f)
    result = SweepResult(out, study.n_runs, len(done), failed, wall, n_workers, n_tasks, run_s)
    if report and table is not None:
        from .plots import plot_all
        result.summary = results.write_summary(study, table, out, force)
        result.figures = plot_all(study, table, out, force)
    return result


def _prepare(out: Path, study: Study, resume: bool, force: bool = False) -> set:
    """Create OUT, record the study; with resume, the run_ids already done (same study only).
    Before anything is written, the files the study will write in OUT are checked
    (results.check_outputs): a folder holding the user's summary.csv is refused."""
    require(not out.exists() or out.is_dir(), f"--out {out}", "is a file, not a folder",
            "pass a folder (it is created if missing)")
    out.mkdir(parents=True, exist_ok=True)
    record = out / STUDY_FILE
    if results.part_files(out) or record.exists():
        require(resume, f"--out {out}", "already holds a study's results",
                "pass --resume (resume=True) to finish it, or pick another folder")
        require(record.is_file(), f"--out {out}", f"holds runs ({results.TABLE}) but no "
                f"{STUDY_FILE}, so which study they belong to is unknown", f"put {STUDY_FILE} "
                "back, or pick another folder (resuming would mix studies)")
        require(_fingerprint(record) == study.fingerprint(), f"--out {out}", "holds a "
                "different study (its axes, scene or settings differ)", "resume with the same "
                "study file, or pick another folder")
        results.check_parts(out, study)
    done = results.done_ids(out)
    results.check_outputs(out, force)
    text = json.dumps({"fingerprint": study.fingerprint(), "n_runs": study.n_runs,
                       "study": study.as_dict()}, indent=1, default=str)
    results.write_output(out, STUDY_FILE, lambda tmp: Path(tmp).write_text(text, "utf-8"), force)
    return done


def _fingerprint(record: Path) -> str:
    """The fingerprint study.json records; a file that is not one is named, not read past."""
    old = results.read_record(record.parent)
    require(isinstance(old, dict) and isinstance(old.get("fingerprint"), str),
            f"--out {record.parent}: {STUDY_FILE}", "holds no study fingerprint",
            "restore the file written by the sweep, or pick another folder")
    return old["fingerprint"]


def make_batches(study: Study, pending, batch_size: int | None, n_workers: int) -> list:
    """Runs grouped by simulated scene (the axes that change the scene, not its noise; for a
    runner study every axis but `seed`), in run_id order within a scene, then packed into
    batches of at most `batch_size`: whole scenes together while they fit (a worker simulates
    each scene once), a larger scene cut into equal parts. The default size gives each worker
    >= 8 tasks and at most 32 runs a task."""
    if not batch_size:
        batch_size = max(1, min(32, math.ceil(len(pending) / (8 * max(n_workers, 1)))))
    scene_axes = [a.name for a in study.axes
                  if a.path not in SPECIAL and not a.path.startswith(("noise", "description"))]
    if isinstance(study, RunnerStudy):  # a function's runs: those that differ only in seed
        scene_axes = [a.name for a in study.axes if a.name != "seed"]
    scenes: dict = {}
    for run in sorted(pending, key=lambda r: r[0]):
        key = json.dumps([run[1][n] for n in scene_axes], default=str)
        scenes.setdefault(key, []).append(run)
    batches, current = [], []
    for runs in scenes.values():
        if len(current) + len(runs) > batch_size and current:
            batches.append(current)
            current = []
        if len(runs) > batch_size:
            parts = math.ceil(len(runs) / batch_size)
            size = math.ceil(len(runs) / parts)
            batches.extend(runs[i:i + size] for i in range(0, len(runs), size))
        else:
            current = current + runs
    return batches + ([current] if current else [])


def _run(client, study: Study, out: Path, batches, n_done: int, progress: bool) -> None:
    from dask.distributed import as_completed
    plan = client.scatter(study.plan(), broadcast=True)
    futures = [client.submit(run_batch, plan, batch, pure=False) for batch in batches]

    def finished():
        for future in as_completed(futures):
            rows = future.result()
            future.release()
            yield rows
    try:
        _write_all(study, out, batches, finished(), n_done, progress)
    except BaseException:
        client.cancel(futures)
        raise


def _write_all(study: Study, out: Path, batches, finished, n_done: int, progress: bool) -> None:
    """Write each batch's rows (from the iterable `finished`) as one part, as they come."""
    from tqdm import tqdm
    values = dict(r for batch in batches for r in batch)
    bar = tqdm(total=study.n_runs, initial=n_done, unit="run", desc="sweep", disable=not progress,
               dynamic_ncols=True, smoothing=0.1, file=sys.stderr)
    try:
        for rows in finished:
            results.write_part(out, results.to_table(study, rows, values.__getitem__))
            bar.update(len(rows))
    finally:
        bar.close()


def _to_stderr(text: str) -> None:
    import sys
    print(text, file=sys.stderr)


@contextmanager
def open_client(workers: int | None, scheduler: str | None, log=_to_stderr):
    """A dask.distributed Client: on the cluster at `scheduler` (address or scheduler file), or
    on a LocalCluster of `workers` processes with one thread each."""
    from dask.distributed import Client
    logging.getLogger("distributed").setLevel(logging.ERROR)
    cluster = None
    if scheduler:
        require(workers is None, "--workers", "does not go with --scheduler",
                "size the cluster where it is started")
        client = _connect(Client, scheduler)
    else:
        cluster = local_cluster(workers)
        client = Client(cluster)
    try:
        info = client.run(worker_info)  # builds each worker's OpenCL runtime, once
        devices = sorted({i["device"] for i in info.values()})
        log(f"sweep: {len(info)} worker(s) at {client.scheduler.address}, device {', '.join(devices)}")
        dash = client.scheduler_info(n_workers=0).get("services", {}).get("dashboard")
        if dash:
            log(f"sweep: Dask dashboard at {client.dashboard_link}")
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


CONNECT_S, WORKERS_S = 5, 20  # a scheduler answers in well under a second on a network


def _connect(Client, scheduler: str):
    """A Client of the cluster at `scheduler` that has a worker; a server that is not a Dask
    scheduler (or none) is one line within CONNECT_S, a cluster without workers within
    WORKERS_S (distributed's own defaults wait 30 s and forever)."""
    file = Path(scheduler).is_file()
    _probe(_file_address(scheduler) if file else scheduler)
    try:
        client = (Client(scheduler_file=scheduler, timeout=f"{CONNECT_S}s") if file
                  else Client(scheduler, timeout=f"{CONNECT_S}s"))
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        raise InputError(f"--scheduler: no Dask scheduler answered at {scheduler} within "
                         f"{CONNECT_S} s ({type(exc).__name__}: {str(exc)[:160]}). Fix: pass "
                         "the address `dask scheduler` prints (tcp://HOST:8786) or its "
                         "--scheduler-file, or leave --scheduler out to run here") from None
    try:
        client.wait_for_workers(1, timeout=WORKERS_S)
    except (OSError, TimeoutError) as exc:
        client.close()
        raise InputError(f"--scheduler: the cluster at {scheduler} has no worker (none joined "
                         f"in {WORKERS_S} s: {type(exc).__name__}). Fix: start one with `dask "
                         f"worker {scheduler}`, or leave --scheduler out") from None
    return client


def _file_address(path: str) -> str:
    """The address in a scheduler file (JSON written by `dask scheduler --scheduler-file`)."""
    try:
        address = json.loads(Path(path).read_text(encoding="utf-8"))["address"]
    except (OSError, ValueError, KeyError, TypeError):
        raise InputError(f"--scheduler: {path} is not a Dask scheduler file (JSON with an "
                         "`address`). Fix: pass the file `dask scheduler --scheduler-file` "
                         "wrote, or the scheduler's tcp://HOST:PORT") from None
    return str(address)


def _probe(address: str) -> None:
    """A tcp:// (or bare HOST:PORT) address must answer as a Dask scheduler does: it sends its
    handshake (msgpack naming the pickle protocol) as soon as a connection opens. distributed
    itself waits without a limit on a server that accepts and says nothing (120 s and more)."""
    import socket
    rest = address.removeprefix("tcp://")
    if "://" in rest or ":" not in rest:
        return  # tls://, ucx://, inproc://: distributed's own connect and timeout
    host, _, port = rest.rpartition(":")
    fix = ("Fix: pass the address `dask scheduler` prints (tcp://HOST:8786) or its "
           "--scheduler-file, or leave --scheduler out to run here")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=CONNECT_S) as sock:
            sock.settimeout(CONNECT_S)
            try:
                hello = sock.recv(4096)
            except TimeoutError:
                hello = b""  # it accepted and said nothing: no Dask scheduler
    except (OSError, ValueError) as exc:
        raise InputError(f"--scheduler: could not reach {address} within {CONNECT_S} s "
                         f"({type(exc).__name__}: {exc}). {fix}") from None
    if b"pickle-protocol" not in hello:
        raise InputError(f"--scheduler: {address} is not a Dask scheduler (it sent no Dask "
                         f"handshake within {CONNECT_S} s). {fix}")


def local_cluster(workers: int | None):
    """Processes, one thread each; on a CPU OpenCL device (PoCL) each worker's runtime gets
    cores / workers threads (POCL_CPU_MAX_CU_NUM) so workers do not fight over cores."""
    from dask.distributed import LocalCluster
    cores = os.cpu_count() or 1
    n = workers or cores
    require(isinstance(n, int) and n >= 1, "--workers", f"must be >= 1, got {n}", "pass e.g. 2")
    env = {"POCL_CPU_MAX_CU_NUM": str(max(1, cores // n))}
    env = {k: v for k, v in env.items() if k not in os.environ}
    from importlib.util import find_spec
    dashboard = ":0" if find_spec("bokeh") else None  # the dashboard needs bokeh
    try:
        return LocalCluster(n_workers=n, threads_per_worker=1, processes=True, env=env,
                            dashboard_address=dashboard, silence_logs=logging.ERROR)
    except OSError as exc:
        raise InputError(f"--workers: could not start {n} local worker processes ({exc}). "
                         "Fix: pass fewer --workers, or start a cluster and pass --scheduler")
