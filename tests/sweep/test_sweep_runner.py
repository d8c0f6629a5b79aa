"""Studies of a function (`runner`, nlos_cl/sweep/runner.py): the same engine in this process
and on a LocalCluster (bit-identical tables), bad runner values named at load, failures
recorded, --resume, the per-worker cache."""
import json
import math
import textwrap

import pytest
import yaml

from nlos_cl.core.errors import InputError
from nlos_cl.sweep import load_study, read_table, sweep, worker_cache
from nlos_cl.sweep.engine import make_batches
from nlos_cl.sweep.runner import RunnerStudy

EXAMPLE = "nlos_cl.sweep.examples:paper_target"
STUDY = {"description": "runner test", "runner": EXAMPLE,
         "axes": [{"name": "x", "values": [3.0, 4.0]}], "seeds": 2,
         "params": {"facet_m": 0.04, "step_m": 0.04}}
TIMES = ("t_run_s", "t_cpu_s")


def same(a, b) -> bool:
    """Every column but the clock's equal; `result` is JSON text written with repr floats, so
    equal text is equal bits."""
    keep = [c for c in a.column_names if c not in TIMES]
    return a.column_names == b.column_names and all(
        a.column(c).to_pylist() == b.column(c).to_pylist() for c in keep)


@pytest.fixture(scope="module")
def in_process(tmp_path_factory):
    out = tmp_path_factory.mktemp("runner")
    return out, sweep(STUDY, out, workers=0, progress=False)


def test_runner_study_in_process(in_process):
    out, result = in_process
    table = result.table()
    assert result.workers == 0 and result.n_runs == table.num_rows == 4
    assert table.column_names == ["run_id", "x", "seed", "result", "t_run_s", "t_cpu_s",
                                  "failure"]
    assert table.column("seed").to_pylist() == [0, 1, 0, 1]
    assert table.column("failure").to_pylist() == [""] * 4
    for row in table.to_pylist():
        value = json.loads(row["result"])
        assert abs(value["position"][0] - row["x"]) < 0.1 and value["error_m"] < 0.2
    assert result.summary is None and result.figures == []  # no error_m column: no report
    assert json.loads((out / "study.json").read_text())["study"]["runner"] == EXAMPLE


def test_runner_study_on_a_local_cluster(in_process, tmp_path):
    result = sweep(STUDY, tmp_path, workers=2, batch_size=1, progress=False)
    assert result.workers == 2 and result.tasks == 4
    assert same(result.table(), in_process[1].table())


def test_runs_that_differ_in_seed_share_a_batch():
    study = load_study(STUDY)
    assert isinstance(study, RunnerStudy)
    batches = make_batches(study, list(study.runs()), 2, 1)
    assert [[values["x"] for _, values in b] for b in batches] == [[3.0, 3.0], [4.0, 4.0]]


def test_resume_runs_only_what_is_missing(in_process, tmp_path):
    """A lost batch (as after a crash) is run again by --resume; the others are kept."""
    sweep(STUDY, tmp_path, workers=0, batch_size=2, progress=False, report=False)
    parts = sorted((tmp_path / "runs.parquet").glob("part-*.parquet"))
    assert len(parts) == 2
    parts[1].unlink()
    kept = parts[0].stat().st_mtime_ns
    result = sweep(STUDY, tmp_path, workers=0, resume=True, progress=False, report=False)
    assert result.n_skipped == 2 and parts[0].stat().st_mtime_ns == kept
    assert same(read_table(tmp_path), in_process[1].table())
    with pytest.raises(InputError, match="different study"):
        sweep({**STUDY, "seeds": 3}, tmp_path, workers=0, resume=True, progress=False)


def _flaky(n: int, scale: float = 1.0) -> dict:
    if n == 2:
        raise ValueError("two is bad")
    return {"n": n * scale, "nan": math.nan}


def test_a_function_from_python_and_failures(tmp_path):
    study = {"runner": _flaky, "axes": [{"name": "n", "range": {"start": 1, "stop": 3,
                                                               "step": 1}}],
             "params": {"scale": 0.5}}
    rows = sweep(study, tmp_path, workers=0, progress=False).table().to_pylist()
    assert [r["failure"] for r in rows] == ["", "ValueError: two is bad", ""]
    assert rows[1]["result"] is None
    assert json.loads(rows[2]["result"])["n"] == 1.5 and math.isnan(
        json.loads(rows[0]["result"])["nan"])
    assert load_study(study).as_dict()["runner"].endswith(":_flaky")


@pytest.mark.parametrize("runner, where", [
    ("no_such_module_xyz:run", r"runner 'no_such_module_xyz:run': cannot import"),
    ("nlos_cl.sweep.examples:missing", r"runner 'nlos_cl.sweep.examples:missing': .* no"),
    ("nlos_cl.sweep.runner:COLUMNS", r"runner 'nlos_cl.sweep.runner:COLUMNS': is not callable"),
    ("paper_target", r"runner: expected 'package.module:function'"),
    (42, r"runner: expected a function"),
])
def test_bad_runner_values_name_the_key(runner, where):
    with pytest.raises(InputError, match=where) as err:
        load_study({**STUDY, "runner": runner})
    assert "Fix:" in str(err.value)


@pytest.mark.parametrize("change, where", [
    ({"axes": [{"name": "height", "values": [1]}]}, "cannot be called with"),
    ({"axes": [{"path": "x", "values": [1]}]}, r"axes\[0\]: .*function's parameters"),
    ({"axes": [{"name": "result", "values": [1]}]}, r"axes\[0\]\.name"),
    ({"params": {"x": 1}}, "name 'x'.* used twice"),
    ({"scene": "s.yaml"}, "study.scene: is not a known key of a runner study"),
    ({"params": [1]}, "params: expected a mapping"),
])
def test_bad_runner_studies_say_where(change, where):
    with pytest.raises(InputError, match=where):
        load_study({**STUDY, **change})


def test_worker_cache_keeps_the_last_calls():
    calls = []

    @worker_cache(keep=2)
    def square(spec, k=1):
        calls.append((spec["a"], k))
        return spec["a"] ** 2 * k

    assert [square({"a": 2}), square({"a": 2}), square({"a": 3}, k=2)] == [4, 4, 18]
    assert calls == [(2, 1), (3, 2)]
    square({"a": 4})  # evicts {"a": 2}, the least recently used
    square({"a": 2})
    assert calls[-1] == (2, 1) and len(calls) == 4


def test_the_example_in_the_docstring_loads():
    from nlos_cl.sweep import examples
    spec = yaml.safe_load(textwrap.dedent(examples.__doc__.split("\n\n", 1)[1]))
    study = load_study(spec)
    assert study.n_runs == 2 * 2 * 3 and study.as_dict()["runner"] == EXAMPLE
