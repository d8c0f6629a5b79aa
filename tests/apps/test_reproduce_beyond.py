"""`nlos-cl reproduce beyond`: the paper's argmax against the model-based estimator, generated
report. One quick run (CI setting) end to end, and the pieces that decide its numbers."""
import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest

from nlos_cl.apps import reproduce as rp
from nlos_cl.apps.reproduce.beyond import cases as bc
from nlos_cl.apps.reproduce.beyond import experiment as beyond
from nlos_cl.apps.reproduce.beyond import report as br
from nlos_cl.apps.reproduce.beyond import sweep as beyond_sweep
from nlos_cl.apps.reproduce.beyond.runs import counter_for
from nlos_cl.apps.reproduce.common import Settings
from nlos_cl.core.errors import InputError
from nlos_cl.localization.estimate import LocatedTarget


def test_beyond_is_an_experiment_but_not_part_of_all():
    assert "beyond" in rp.EXPERIMENTS
    assert "beyond" not in rp.PAPER_EXPERIMENTS
    assert set(rp.PAPER_EXPERIMENTS) == set(rp.EXPERIMENTS) - {"beyond", "tracking", "real",
                                                               "draws", "flood", "scenarios"}


def test_cases_come_from_the_yaml_and_quick_is_a_subset():
    full, quick = bc.config(False), bc.config(True)
    assert "quick" not in full
    assert full["grid"]["x"] == [1, 2, 3, 4, 5] and full["grid"]["y"] == [1, 2, 3, 4, 5]
    for key in ("grid", "layout_grid"):
        assert set(quick[key]["x"]) <= set(full[key]["x"])
    assert len(quick["photons"]["signal_photons"]) < len(full["photons"]["signal_photons"])
    sizes = {len(bc.layout(full, n).spots) for n in ("paper", "circle8", "spad32", "spad32_sub")}
    assert sizes == {3, 8, 1024, 64}
    assert not bc.layout(full, "paper").height_observable
    assert bc.layout(full, "triangle").height_observable


def test_inside95_uses_the_observable_axes():
    cov = np.diag([0.01 ** 2, 0.01 ** 2, np.inf])
    truth = np.zeros(3)
    near = LocatedTarget(np.array([0.02, 0.0, 5.0]), cov)  # z unobservable: ignored
    far = LocatedTarget(np.array([0.03, 0.0, 0.0]), cov)  # 9 > chi2(2) 95 % = 5.99
    assert bc.inside95(near, truth) is True
    assert bc.inside95(far, truth) is False
    assert bc.inside95(LocatedTarget(np.zeros(3)), truth) is None


def test_targets_are_matched_by_assignment():
    a, b = LocatedTarget(np.array([1.0, 1.0, 0.0])), LocatedTarget(np.array([1.2, 1.0, 0.0]))
    truths = np.array([[1.25, 1.0, 0.0], [1.05, 1.0, 0.0]])
    assert bc.match([a, b], truths) == [b, a]
    assert bc.match([a], truths) == [a, a]  # fewer found: the nearest
    assert bc.match([], truths) == [None, None]


def test_collinear_error_is_measured_in_what_the_spots_observe():
    lay = bc.Layout("line", "line", np.array([[-0.5, 0, 0], [-1.0, 0, 0]]), False)
    truth = np.array([3.0, 2.0, 0.4])
    rotated = np.array([3.0, math.hypot(2.0, 0.4), 0.0])  # about the spots' line (x axis)
    errors = bc._errors("m", rotated, truth, lay.line())
    assert errors["m_errline_m"] == pytest.approx(0.0, abs=1e-9)
    assert errors["m_err3d_m"] > 0.3
    np.testing.assert_allclose(lay.observed(truth), rotated, atol=1e-12)  # the 95 % test's truth
    seen = bc.Layout("tri", "tri", np.array([[-0.5, 0, 0], [-1.0, 0, 0.5]]), False)
    assert seen.line() is None and np.array_equal(seen.observed(truth), truth)


def test_wilson_interval():
    lo, hi = br.wilson(95, 100)
    assert lo < 0.95 < hi and 0.88 < lo and hi < 0.98


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("beyond")
    doc = out / "report.md"
    proc = subprocess.run([sys.executable, "-m", "nlos_cl.apps.cli", "reproduce", "beyond", "--quick",
                           "--json", "--out", str(out), "--doc", str(doc)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return out, doc, json.loads(proc.stdout)


def test_quick_run_writes_the_report_csvs_and_figure(quick_run):
    out, doc, summary = quick_run
    for name in ("beyond.csv", "beyond-summary.csv", "beyond-coverage.csv"):
        assert (out / name).stat().st_size > 100
    assert (out / "beyond.png").stat().st_size > 10_000
    text = doc.read_text()
    assert "do not edit by hand" in text and "--quick" in text
    for section in br.TEXT["sections"].values():
        assert section["short"] in text
    # the targets' checks are --json's (for the note), not the page's
    assert "| met |" not in text and not re.search(r"\b(goals?|issue|targets, checked)\b",
                                                   text, re.IGNORECASE)
    sections = {r["section"] for r in summary["summary"]}
    assert sections == set(br.TEXT["sections"])
    assert len(summary["goals"]) == len(br.TEXT["goals"])


def test_quick_run_numbers_are_sane(quick_run):
    _, _, summary = quick_run
    rows = {(r["section"], r["measure"]): r for r in summary["summary"]}
    grid = rows[("grid", "err3d")]
    assert grid["model_failed"] == 0
    assert grid["model_mean_m"] < grid["paper_mean_m"]  # the paper's bias is ~5 cm; the model's mm
    assert grid["model_mean_m"] < 0.03
    two = rows[("two", "err3d")]
    assert two["errors"] == 2 * two["frames"]  # both truths scored per frame
    height = [r for r in summary["summary"] if r["section"] == "height"]
    assert {"dz", "errline"} <= {r["measure"] for r in height}
    assert any("unobservable" in r["note"] for r in height if r["measure"] == "errline")


def _same_rows(new, old) -> bool:
    """Equal in every column but the model's wall time (NaN equal to NaN)."""
    def cell(v):
        return "nan" if isinstance(v, float) and math.isnan(v) else v
    strip = [[{k: cell(v) for k, v in r.items() if k != "model_s"} for r in rows]
             for rows in (new, old)]
    return len(new) == len(old) and strip[0] == strip[1]


def test_the_sweep_gives_the_old_loops_rows(tmp_path):
    """One tiny case through the sweep engine (a runner study, in this process) against the
    loop `reproduce beyond` ran before: simulate once, then run_frame + frame_rows per seed."""
    from dataclasses import replace
    s = replace(Settings.make(quick=True, seeds=2), facet_m=0.04, grid_step_m=0.04)
    cfg = bc.config(True)
    lay, size, pos = bc.layout(cfg, "paper"), cfg["paper_target"]["size"], (4.0, 2.0, 0.0)
    entries = [beyond._entry("grid", "tiny", [beyond_sweep.frames("grid", "tiny", lay,
                                                                  [(size, pos)], 2)]),
               beyond._entry("photons", "tiny photons", [beyond_sweep.frames(
                   "photons", "tiny photons", lay, [(size, pos)], 1, photons=1000)])]
    beyond_sweep.run_entries(entries, cfg, s, tmp_path)
    clean, truths = bc.simulate(lay, s, [(size, pos)]), np.asarray([pos])
    old = [r for seed in (0, 1) for r in bc.frame_rows(
        "grid", "tiny", lay, seed, bc.run_frame(clean, seed, lay, s.grid(), s), truths)]
    frame = bc.run_frame(clean, 0, lay, s.grid(), s, noise=counter_for(clean, 1000))
    old_photons = bc.frame_rows("photons", "tiny photons", lay, 0, frame, truths)
    assert _same_rows(entries[0]["rows"], old) and _same_rows(entries[1]["rows"], old_photons)
    assert entries[0]["rows"][0]["model_err3d_m"] < 0.1  # a real fit, not two equal failures
    assert (tmp_path / beyond_sweep.FOLDER / "study.json").is_file()  # the table is kept
    with pytest.raises(InputError, match="1 of 3 frame"):  # a failed run is not dropped
        import pyarrow as pa
        runs = pa.table({"run_id": [0, 1, 2], "result": ["[]", None, "[]"],
                         "failure": ["", "ValueError: x", ""]})
        beyond_sweep.fill(entries, runs)


def test_the_quick_study_is_one_run_per_frame():
    from nlos_cl.sweep import load_study
    s = Settings.make(quick=True)
    cfg = bc.config(True)
    entries = [e for _, fn in beyond.SECTIONS for e in fn(cfg, s)]
    study = load_study(beyond_sweep.study(entries, cfg, s))
    frames = sum(len(f["seeds"]) for e in entries for f in e["frames"])
    assert study.n_runs == frames and frames >= 8
    seeds = [v["seed"] for _, v in study.runs()]
    assert seeds[-1] == 1000  # the coverage case's seeds start at 1000
