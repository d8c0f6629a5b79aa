"""`nlos-cl reproduce tracking` (docs/tracking.md's tables): one --quick run end to end through
the CLI, its tables' columns and whether their numbers are physically plausible; tracking.yaml
checked with a one-line error; the page's markers."""
import copy
import csv
import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from nlos_cl.apps import reproduce as rp
from nlos_cl.apps.reproduce.tracking import cases as tc, experiment as tracking
from nlos_cl.apps.reproduce.tracking import report as tracking_report
from nlos_cl.apps.reproduce.common import Result
from nlos_cl.core.errors import InputError

DOC = Path(__file__).resolve().parents[2] / "docs" / "tracking.md"
PATH_COLUMNS = ["case", "frames", "frames_without_track", "per_frame_rms_m", "per_frame_max_m",
                "filter_rms_m", "filter_max_m", "ratio_filter", "goal_filter", "lag_rms_m",
                "lag_max_m", "ratio_lag", "goal_lag", "smoother_rms_m", "smoother_max_m",
                "ratio_smoother", "goal_smoother", "causal_bound"]
# The walker is a 0.3 m wide plate: a position more than half its width (0.15 m) from its
# centre is off the target, so every tracked RMS error must be below that. The model estimator
# fits the plate's centre with ~1 cm sd at 10 dB (docs/model-estimator.md): 3 cm is 3 sd.
OFF_TARGET_M, MODEL_M = 0.15, 0.03


def _read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("tracking")
    proc = subprocess.run([sys.executable, "-m", "nlos_cl.apps.cli", "reproduce", "tracking",
                           "--quick", "--json", "--out", str(out)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return out, json.loads(proc.stdout)


def test_tracking_is_an_experiment_but_not_part_of_all():
    assert "tracking" in rp.EXPERIMENTS and "tracking" not in rp.PAPER_EXPERIMENTS


def test_quick_run_writes_every_section(quick_run):
    out, summary = quick_run
    index = _read(out / "tracking.csv")
    assert [r["section"] for r in index] == list(tc.SECTIONS)  # tracking.yaml's order
    assert sum(float(r["seconds"]) for r in index) < 60  # --quick: well under a minute
    page = (out / "tracking.md").read_text()
    for name in tc.SECTIONS:
        assert (out / f"tracking-{name}.csv").stat().st_size > 50
        assert f"<!-- reproduce tracking:{name} -->" in page
        assert summary["markdown"][name] in page
    assert summary["warm_start"] is True and summary["quick"] is True


def test_quick_path_tables_have_the_columns_and_plausible_errors(quick_run):
    out, summary = quick_run
    lines = _read(out / "tracking-lines.csv")
    assert list(lines[0]) == PATH_COLUMNS
    assert len(lines) == 4  # quick: 2 paths x 1 layout x 2 estimators
    assert summary["markdown"]["lines"].count("\n") == len(lines) + 1  # header, rule, rows
    for r in lines:
        errors = [float(r[k]) for k in PATH_COLUMNS if k.endswith("_rms_m")]
        assert all(math.isfinite(e) and 0 < e < OFF_TARGET_M for e in errors), r
        assert r["frames_without_track"] == "0"
        # the bound knows the path and uses earlier frames too: below the frame's own error
        assert 0 < float(r["causal_bound"]) < 1
        if r["case"].endswith("model"):
            assert float(r["per_frame_rms_m"]) < MODEL_M, r
    box = {r["case"]: r for r in _read(out / "tracking-box.csv")}
    # the box stands >= 1.1 m from the walker's path: without removal the argmax follows it
    assert float(box["box, no removal, paper"]["per_frame_rms_m"]) > 0.5
    for case in ("no box, paper", "box, reference (mean of 10 target-free frames), paper"):
        assert float(box[case]["filter_rms_m"]) < OFF_TARGET_M


def test_quick_synthetic_crossing_speed_and_memory_are_plausible(quick_run):
    out, _ = quick_run
    synthetic = _read(out / "tracking-synthetic.csv")
    assert list(synthetic[0]) == ["accel_sigma", "path", "filter_rms_m", "per_frame_rms_m",
                                  "ratio"]
    for r in synthetic:
        assert float(r["per_frame_rms_m"]) == pytest.approx(0.008 * math.sqrt(2), rel=0.15)
        if r["path"] == "straight":  # between the causal bound (0.42 at 50 frames) and 1
            assert 0.3 < float(r["ratio"]) < 1.0
    (seed0,) = _read(out / "tracking-crossing.csv")
    assert seed0["kept"] == "True"  # seed 0 keeps both identities (deterministic seeds)
    speed = {r["estimator"]: float(r["frames_per_s"]) for r in _read(out / "tracking-speed.csv")}
    assert set(speed) == {"paper", "model"} and all(v > 0 for v in speed.values())
    memory = _read(out / "tracking-memory.csv")
    assert {r["max_history"] for r in memory} == {"20", "None"}  # quick: 200 frames
    assert all(float(r["peak_rss_mib"]) > 10 for r in memory)


def test_a_bad_case_is_one_line_naming_its_field():
    data = copy.deepcopy(tc.load_data("tracking.yaml", tc.__package__))
    data["lines"]["frames"] = 0
    with pytest.raises(InputError) as caught:
        tc.config(False, data)
    message = str(caught.value)
    assert message.startswith("tracking.yaml lines.frames: expected a positive integer, got 0")
    assert "\n" not in message and "Fix:" in message
    data = copy.deepcopy(tc.load_data("tracking.yaml", tc.__package__))
    data["quick"]["box"]["layout"] = "9-spot"  # a name the layouts do not have
    with pytest.raises(InputError, match=r"^tracking.yaml quick.box.layout: unknown layout"):
        tc.config(True, data)


def test_quick_is_the_full_setting_made_smaller():
    full, quick = tc.config(False), tc.config(True)
    assert "quick" not in full and full["sections"] == quick["sections"]
    for name in ("lines", "box", "crossing", "memory"):
        assert quick[name]["frames"] < full[name]["frames"]
    assert full["lines"]["frames"] == 50 and full["crossing"]["seeds"] == 10  # the page's setting
    assert tc.Common.of(full, cold=True).tracker["warm_start"] is False


def test_the_page_has_markers_for_every_section_and_splice_keeps_the_prose(tmp_path):
    doc = tmp_path / "tracking.md"
    doc.write_text(DOC.read_text())
    texts = {name: f"new {name} table" for name in tc.SECTIONS}
    tracking.write_doc(Result("tracking", "", [], {"warm_start": True, "markdown": texts}), doc)
    new, old = doc.read_text(), DOC.read_text()
    assert all(f"{t}\n<!-- /reproduce tracking:{n} -->" in new for n, t in texts.items())
    assert new.split("<!--")[0] == old.split("<!--")[0]  # the prose before the first table
    with pytest.raises(InputError, match="cold run"):
        tracking.write_doc(Result("tracking", "", [], {"warm_start": False, "markdown": {}}), doc)
    (tmp_path / "other.md").write_text("no markers here\n")
    with pytest.raises(InputError, match="no markers for section lines"):
        tracking_report.splice(tmp_path / "other.md", {"lines": "t"})
    assert (tmp_path / "other.md").read_text() == "no markers here\n"  # nothing written
