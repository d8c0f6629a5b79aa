"""Sweeps on real Dask: a LocalCluster with 1 and 2 workers (bit-identical tables), a cluster
started separately (`dask scheduler` + `dask worker`), --resume after a killed run; and the
same study in this process (workers=0), bit-identical too."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.dataset as ds
import pytest
import yaml

from nlos_cl.sweep import read_table, sweep
from nlos_cl.sweep.runs import TIMING_COLUMNS

STUDY = {
    "description": "test study",
    "scene": {"setup": {"detector_spots": [[-0.5, 0, 0], [-1, 0, 0], [-1.5, 0, 0]]},
              "targets": [{"shape": "rectangle", "size_m": [0.3, 1.6], "position": [4, 2, 0]}],
              "facet_size_m": 0.02, "time_axis": {"dt_s": 1e-11}, "noise": {"snr_db": 10}},
    "axes": [{"path": "targets[0].position[0]", "name": "x", "values": [3, 4]}],
    "estimators": ["paper", "model"],
    "seeds": 2,
}
N_RUNS = 8
BIN = Path(sys.executable).parent


def same(a, b) -> bool:
    """Tables bit-identical in every column but the timings (which are the clock's)."""
    keep = [c for c in a.column_names if c not in TIMING_COLUMNS]
    if a.column_names != b.column_names or a.num_rows != b.num_rows:
        return False
    for name in keep:
        x, y = a.column(name), b.column(name)
        if pa.types.is_floating(x.type):  # bits, so NaN == NaN and -0.0 != 0.0
            if not np.array_equal(x.to_numpy().view(np.int64), y.to_numpy().view(np.int64)):
                return False
        elif x.to_pylist() != y.to_pylist():
            return False
    return True


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The study on a LocalCluster of 1 worker, all runs in one task."""
    out = tmp_path_factory.mktemp("one")
    result = sweep(STUDY, out, workers=1, batch_size=N_RUNS, progress=False)
    assert result.tasks == 1 and result.workers == 1
    return result.table()


def test_local_cluster_table(reference):
    assert reference.num_rows == N_RUNS
    assert reference.column("run_id").to_pylist() == list(range(N_RUNS))
    assert reference.column("failure").to_pylist() == [""] * N_RUNS
    errors = reference.column("error_m").to_pylist()
    assert max(errors) < 0.3, errors
    model = [r for r in reference.to_pylist() if r["estimator"] == "model"]
    assert all(r["cov_xx_m2"] > 0 for r in model)  # the model reports a covariance


def test_two_workers_give_the_same_table(reference, tmp_path):
    result = sweep(STUDY, tmp_path, workers=2, batch_size=1, progress=False)
    assert result.workers == 2 and result.tasks == N_RUNS
    assert same(result.table(), reference)
    assert (tmp_path / "summary.csv").is_file() and (tmp_path / "errors_by_axis.png").is_file()
    assert len(list((tmp_path / "runs.parquet").glob("part-*.parquet"))) == N_RUNS


def test_in_process_gives_the_same_table(reference, tmp_path):
    """workers=0: the same batches run in this process, no Dask; the same table."""
    result = sweep(STUDY, tmp_path, workers=0, batch_size=3, progress=False, report=False)
    assert result.workers == 0 and result.tasks == 4  # 2 scenes of 4 runs, halved
    assert same(result.table(), reference)


def _start(args, **kw):
    return subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True, **kw)


def _stop(proc):
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(20)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def test_separately_started_cluster(reference, tmp_path):
    """`dask scheduler` and `dask worker` as their own processes, on free ports."""
    sched_file = tmp_path / "scheduler.json"
    scheduler = _start([str(BIN / "dask"), "scheduler", "--port", "0", "--no-dashboard",
                        "--scheduler-file", str(sched_file)])
    worker = None
    try:
        for _ in range(300):
            if sched_file.is_file() and sched_file.stat().st_size:
                break
            time.sleep(0.1)
        worker = _start([str(BIN / "dask"), "worker", "--scheduler-file", str(sched_file),
                         "--nworkers", "1", "--nthreads", "1", "--no-dashboard"])
        result = sweep(STUDY, tmp_path / "out", scheduler=str(sched_file), batch_size=3,
                       progress=False)
        assert result.workers == 1 and result.tasks == 4  # 2 scenes of 4 runs, halved
        assert same(result.table(), reference)
    finally:
        for proc in (worker, scheduler):
            if proc is not None:
                _stop(proc)


def test_resume_after_kill(reference, tmp_path):
    """Kill the command (and its cluster) after its first batch; --resume runs only the rest
    and the table equals the uninterrupted one."""
    study = tmp_path / "study.yaml"
    study.write_text(yaml.safe_dump(STUDY))
    out = tmp_path / "out"
    parts = out / "runs.parquet"
    proc = _start([sys.executable, "-m", "nlos_cl.apps.sweep_cmd", str(study), "--out", str(out),
                   "--workers", "1", "--batch-size", "1", "--no-progress"])
    try:
        deadline = time.time() + 240
        while time.time() < deadline and proc.poll() is None:
            if parts.is_dir() and any(parts.glob("part-*.parquet")):
                break
            time.sleep(0.02)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)  # the client, its scheduler and its worker
        proc.wait()
    before = {p.name: p.stat().st_mtime_ns for p in parts.glob("part-*.parquet")}
    done = set(read_table(out).column("run_id").to_pylist())
    assert 1 <= len(done) < N_RUNS, "the kill came too late to test resuming"
    result = sweep(study, out, workers=1, resume=True, progress=False)
    assert result.n_skipped == len(done)
    after = {p.name: p.stat().st_mtime_ns for p in parts.glob("part-*.parquet")}
    assert all(after[name] == mtime for name, mtime in before.items())  # untouched
    raw = ds.dataset(parts, format="parquet").to_table()
    assert raw.num_rows == N_RUNS  # no run written twice
    assert same(read_table(out), reference)


def test_out_folder_is_not_overwritten(reference, tmp_path):
    from nlos_cl.core.errors import InputError
    (tmp_path / "study.json").write_text('{"fingerprint": "other"}')
    with pytest.raises(InputError, match="--resume"):
        sweep(STUDY, tmp_path, workers=1, progress=False)
    with pytest.raises(InputError, match="different study"):
        sweep(STUDY, tmp_path, workers=1, resume=True, progress=False)
