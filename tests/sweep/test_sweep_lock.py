"""Sweeps lock their folder (nlos_cl/sweep/folder_lock.py, issue 59 item 4): a second sweep on
a folder another is writing fails at once in one line; --resume reads what is done under the
lock, so no run is written twice into runs.parquet."""
import json
import os
import subprocess
import sys
import textwrap
import time

import pytest

from nlos_cl.core.errors import InputError
from nlos_cl.sweep import read_table, sweep
from nlos_cl.sweep.folder_lock import LOCK_FILE, folder_lock

N_RUNS = 8


@pytest.fixture
def slow_study(tmp_path, monkeypatch):
    (tmp_path / "my_slow_runs.py").write_text(textwrap.dedent("""
        import time
        def run(n):
            time.sleep(0.4)
            return {"n": n}
    """))
    monkeypatch.syspath_prepend(str(tmp_path))
    return {"runner": "my_slow_runs:run", "axes": [{"name": "n", "values": list(range(N_RUNS))}],
            "batch_size": 1}


def _start(study, out, cwd):
    code = ("import json, sys; import nlos_cl as nl; nl.sweep(json.loads(sys.argv[1]), "
            "sys.argv[2], workers=0, progress=False, report=False, resume=True, "
            "allow_runner=['my_slow_runs'])")
    return subprocess.Popen([sys.executable, "-c", code, json.dumps(study), str(out)], cwd=cwd,
                            env={**os.environ, "PYTHONPATH": os.pathsep.join([str(cwd), os.environ.get("PYTHONPATH", "")])},
                            stderr=subprocess.PIPE, text=True)


def test_a_second_sweep_on_a_busy_folder_fails_at_once_and_nothing_is_run_twice(
        slow_study, tmp_path):
    out = tmp_path / "out"
    first = _start(slow_study, out, tmp_path)
    try:
        deadline = time.monotonic() + 60
        while not list((out / "runs.parquet").glob("part-*.parquet")):  # it has begun writing
            assert first.poll() is None and time.monotonic() < deadline, first.stderr.read()
            time.sleep(0.05)
        start = time.monotonic()
        with pytest.raises(InputError, match=r"^--out .*: another nlos-cl sweep is writing "
                                             r"this folder now .*Fix: wait") as err:
            sweep(slow_study, out, workers=0, progress=False, report=False, resume=True,
                  allow_runner=["my_slow_runs"])
        assert time.monotonic() - start < 2.0 and "\n" not in str(err.value)  # at once
    finally:
        assert first.wait(timeout=120) == 0, first.stderr.read()
    ids = read_table(out).column("run_id").to_pylist()
    assert sorted(ids) == list(range(N_RUNS))  # each run once
    again = sweep(slow_study, out, workers=0, progress=False, report=False, resume=True,
                  allow_runner=["my_slow_runs"])  # the lock went with the first process
    assert again.n_skipped == N_RUNS and read_table(out).num_rows == N_RUNS


def test_the_lock_is_held_for_the_whole_sweep_and_is_a_plain_file(slow_study, tmp_path):
    out = tmp_path / "out"
    with folder_lock(out), pytest.raises(InputError, match="another nlos-cl sweep"):
        sweep(slow_study, out, workers=0, progress=False, allow_runner=["my_slow_runs"])
    assert not (out / "study.json").exists()  # refused before the record was read or written
    (out / LOCK_FILE).unlink()
    (out / LOCK_FILE).symlink_to(tmp_path / "elsewhere")
    with pytest.raises(InputError, match=rf"cannot open its lock file {LOCK_FILE}"):
        sweep(slow_study, out, workers=0, progress=False, allow_runner=["my_slow_runs"])
    assert not (tmp_path / "elsewhere").exists()  # a link is not followed
