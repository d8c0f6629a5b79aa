"""The study's table: one row per run, written as Parquet one file per finished batch into
DIR/runs.parquet/ (a dataset folder, read back as one table), and the summary made from it.

Each part file is written under a hidden name and renamed into place, so a crash or Ctrl-C
leaves only whole parts behind; `--resume` reads the run_ids already there and skips them.
"""
from __future__ import annotations

import json
import os
import re
import uuid
from pathlib import Path

import pyarrow as pa

from ..core.errors import InputError, require

from .runner import COLUMNS as RUNNER_COLUMNS, RunnerStudy
from .runs import record_columns
from .study import Study

TABLE = "runs.parquet"
STUDY_FILE = "study.json"
OUTPUTS = (STUDY_FILE, "summary.csv", "errors_by_axis.png", "error_map.png")  # OUT/ files


MAX_RECORD_BYTES = 256 << 20  # study.json: the study expanded (ranges as lists) and bounded


def read_record(out):
    """OUT/study.json parsed, or an InputError naming it: not a regular file (a FIFO would
    block), larger than MAX_RECORD_BYTES, not UTF-8 JSON, or nested too deep to parse (a
    100,000-deep file is a RecursionError inside json)."""
    from ..io.safe_write import require_file
    record = Path(out) / STUDY_FILE
    where, fix = f"--out {Path(out)}: {STUDY_FILE}", ("restore the file the sweep wrote, or "
                                                      "pick another folder")
    require_file(record, where, fix)
    with open(record, "rb") as fh:
        data = fh.read(MAX_RECORD_BYTES + 1)
    require(len(data) <= MAX_RECORD_BYTES, where, f"is larger than {MAX_RECORD_BYTES >> 20} "
            "MiB, not a record a sweep wrote", fix)
    try:
        return json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        problem = "nests too deep" if isinstance(exc, RecursionError) else type(exc).__name__
        raise InputError(f"--out {Path(out)}: {STUDY_FILE} is not readable JSON ({problem}), "
                         f"so its runs cannot be matched to a study. Fix: {fix}") from None


def is_study_folder(out) -> bool:
    """Whether OUT holds a study record (study.json with a fingerprint), written by a sweep:
    its OUTPUTS are then a sweep's, replaced on --resume (folders from before the manifest of
    nlos_cl.io.safe_write included)."""
    try:
        record = read_record(out)
    except (InputError, OSError):
        return False
    return isinstance(record, dict) and "fingerprint" in record


def write_output(out, name: str, write, force: bool = False) -> Path:
    """OUT/name written atomically by write(tmp), under safe_write's rule: a file there that no
    sweep wrote is replaced only with force (nlos-cl sweep --force)."""
    from ..io.safe_write import atomic_write
    return atomic_write(Path(out) / name, write, keep_unless=lambda p: is_study_folder(p.parent),
                        force=force, what="--out", kind="a sweep's output")


def check_outputs(out, force: bool = False) -> None:
    """Before any run: every file the study will write in OUT may be written (see
    write_output), so a user's summary.csv is refused now, not replaced at the end."""
    from ..io.safe_write import require_writable
    for name in OUTPUTS:
        require_writable(Path(out) / name, keep_unless=lambda p: is_study_folder(p.parent),
                         force=force, what="--out", kind="a sweep's output")


def axis_type(values) -> pa.DataType:
    """int64 for whole numbers, float64 for numbers, string for text; anything else (lists,
    mappings) is written as its JSON text."""
    if all(isinstance(v, int) and not isinstance(v, bool) for v in values):
        return pa.int64()
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        return pa.float64()
    return pa.string()


def axis_cell(value, kind: pa.DataType):
    if kind == pa.string() and not isinstance(value, str):
        return json.dumps(value, separators=(",", ":"))
    return float(value) if kind == pa.float64() else value


def schema(study: Study) -> pa.Schema:
    fields = [pa.field("run_id", pa.int64())]
    fields += [pa.field(a.name, axis_type(a.values)) for a in study.axes]
    if isinstance(study, RunnerStudy):  # result (JSON text), t_run_s, t_cpu_s
        fields += [pa.field(c, pa.string() if c == "result" else pa.float64())
                   for c in RUNNER_COLUMNS]
    else:
        fields += [pa.field(c, pa.float64()) for c in record_columns(study.settings["record"])]
    return pa.schema(fields + [pa.field("failure", pa.string())])


def to_table(study: Study, rows, values_of) -> pa.Table:
    """A batch's rows (from the workers) with the axis values of each run_id added."""
    sch = schema(study)
    kinds = {a.name: axis_type(a.values) for a in study.axes}
    columns = {name: [] for name in sch.names}
    for row in rows:
        values = values_of(row["run_id"])
        for name in sch.names:
            if name in kinds:
                columns[name].append(axis_cell(values[name], kinds[name]))
            else:
                columns[name].append(row[name])
    return pa.table(columns, schema=sch)


def table_dir(out) -> Path:
    out = Path(out)
    return out if out.name == TABLE else out / TABLE


def write_part(out, table: pa.Table) -> Path:
    """One part file, atomically (hidden name, then renamed): readers never see half a part."""
    import pyarrow.parquet as pq
    folder = table_dir(out)
    folder.mkdir(parents=True, exist_ok=True)
    first = int(min(table.column("run_id").to_pylist()))
    final = folder / f"part-{first:09d}-{uuid.uuid4().hex[:8]}.parquet"
    hidden = folder / f".{final.name}.tmp"
    pq.write_table(table, hidden)
    with open(hidden, "rb") as f:
        os.fsync(f.fileno())
    os.replace(hidden, final)
    return final


PART = re.compile(r"part-\d{9}-[0-9a-f]{8}\.parquet")  # write_part's names


def part_files(out) -> list[Path]:
    """What the table folder holds, but the hidden names (parts being written, as pyarrow's
    reader skips them too)."""
    folder = table_dir(out)
    if not folder.is_dir():
        return [folder] if folder.exists() else []
    return sorted(p for p in folder.iterdir() if not p.name.startswith((".", "_")))


def check_parts(out, study: Study) -> None:
    """Before --resume counts what is done: every file in OUT/runs.parquet/ is a whole part of
    this very study (its name, its columns, its runs' axis values), so a truncated part, a
    stray file or another study's part is named, not read as results or mixed in."""
    import pyarrow.parquet as pq
    where, expected, runs = f"--out {out}", schema(study), None
    for path in part_files(out):
        name = f"{TABLE}/{path.name}"
        require(path.is_file() and bool(PART.fullmatch(path.name)), where, f"{name} is not a "
                "part nlos_cl wrote (it would be read as results)", "move it out of the folder")
        try:
            part = pq.read_table(path)
        except (pa.ArrowException, OSError, ValueError) as exc:
            raise InputError(f"{where}: {name} is truncated or corrupted ({type(exc).__name__}: "
                             f"{' '.join(str(exc).split())[:200]}). Fix: delete that part; "
                             "--resume runs its runs again") from None
        require(part.schema.remove_metadata().equals(expected), where, f"{name} has other "
                "columns than this study's table (it belongs to another study)",
                "resume with the study that wrote it, or move the part out")
        runs = dict(study.runs()) if runs is None else runs
        ids = part.column("run_id").to_pylist()
        bad = next((i for i in ids if i not in runs), None)
        require(bad is None, where, f"{name} holds run {bad}, but this study has "
                f"{study.n_runs} runs (it belongs to another study)", "move the part out")
        axis_rows = to_table(study, [{**dict.fromkeys(expected.names), "run_id": i}
                                     for i in ids], runs.__getitem__)
        names = [a.name for a in study.axes]
        require(axis_rows.select(names).equals(part.select(names)), where, f"{name} holds "
                "runs whose axis values differ from this study's", "move the part out (it "
                "belongs to another study)")


def read_table(out, columns=None) -> pa.Table:
    """DIR/runs.parquet (a dataset folder or a single file) as one table, sorted by run_id,
    each run once."""
    import pyarrow.dataset as ds
    path = table_dir(out)
    if not path.exists():
        return None
    table = ds.dataset(path, format="parquet").to_table(columns=columns)
    if table.num_rows == 0:
        return table
    table = table.sort_by("run_id")
    ids = table.column("run_id").to_numpy()
    if len(ids) > 1 and (ids[1:] == ids[:-1]).any():  # a run written twice: keep one
        keep = [True] + list(ids[1:] != ids[:-1])
        table = table.filter(pa.array(keep))
    return table


def done_ids(out) -> set:
    """run_ids already in the table (for --resume)."""
    table = read_table(out, columns=["run_id"])
    return set() if table is None else set(table.column("run_id").to_pylist())


def summary(study: Study, table: pa.Table) -> pa.Table | None:
    """Mean, std (population), max and count of error_m per combination of the axes other than
    the seed, over the runs that did not fail; rows in the study's order."""
    import pyarrow.compute as pc
    if table is None or "error_m" not in table.column_names:
        return None
    ok = table.filter(pc.equal(table.column("failure"), ""))
    keys = [a.name for a in study.axes if a.name != "seed"]
    aggs = [("error_m", "mean"), ("error_m", "stddev"), ("error_m", "max"), ("error_m", "count"),
            ("run_id", "min")]
    if "t_run_s" in ok.column_names:
        aggs.append(("t_run_s", "mean"))
    grouped = ok.group_by(keys, use_threads=False).aggregate(aggs).sort_by("run_id_min")
    names = {"error_m_mean": "error_mean_m", "error_m_stddev": "error_std_m",
             "error_m_max": "error_max_m", "error_m_count": "runs", "t_run_s_mean": "t_run_mean_s"}
    grouped = grouped.drop_columns(["run_id_min"])
    return grouped.rename_columns([names.get(c, c) for c in grouped.column_names])


def write_summary(study: Study, table: pa.Table, out, force: bool = False) -> Path | None:
    import pyarrow.csv as pcsv
    table = summary(study, table)
    if table is None:
        return None
    return write_output(out, "summary.csv", lambda tmp: pcsv.write_csv(table, tmp), force)
