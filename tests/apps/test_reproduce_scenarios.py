"""`nlos-cl reproduce scenarios`: the draws are pure functions of their seed and keep the issue's
ranges; a short run through the command line (three draws of three families) writes the CSV,
the summary and the page with their columns, and counts a draw whose answer is forced wrong as
a failure; the failure rule itself on made-up answers (a wrong position, a missed, an extra or
a shadowed target, a refusal, a crash; a sequence's frames)."""
import copy
import csv
import json
import math

import numpy as np
import pytest

from nlos_cl.apps import cli
from nlos_cl.apps import reproduce as rp
from nlos_cl.apps.reproduce.scenarios import draws as dr
from nlos_cl.apps.reproduce.scenarios import run, score

CFG = dr.config()
ROW_COLUMNS = {"index", "family", "kind", "shapes", "truths", "layout", "spots", "command",
               "exit", "found", "right_k", "error_m", "errors_m", "lit", "failed", "why",
               "warned", "in_declared_shadow", "said", "simulate_s", "answer_s"}
SUMMARY_COLUMNS = {"family", "draws", "failures", "failure_rate", "right_k_rate", "median_m",
                   "p90_m", "worst_m", "failures_unwarned", "refused_or_crashed"}


def test_scenarios_is_an_experiment_but_not_part_of_all():
    assert "scenarios" in rp.EXPERIMENTS and "scenarios" not in rp.PAPER_EXPERIMENTS


def test_the_ranges_are_the_issues():
    """Never narrowed: plates 0.2-1.2 m wide and up to 1.8 m tall, 1-3 targets, TDC bins of
    16 ps to 1.5 ns, walls jittered by 3 cm, every family of the issue."""
    assert CFG["sizes"]["plate"] == {"width_m": [0.2, 1.2], "height_m": [0.2, 1.8]}
    assert CFG["multi"]["targets"] == [1, 2, 3]
    assert CFG["bins"]["tdc_s"] == [16e-12, 1.5e-9]
    assert CFG["walls"]["bump_m"] == 0.03
    assert set(CFG["walls"]["kinds"]) == {"tilted", "moved", "tilted_moved", "bumpy"}
    assert set(CFG["families"]) == {"clutter", "multi", "shapes", "records", "bins", "counts",
                                    "walls", "occluders"}


def test_a_draw_is_a_pure_function_of_its_seed_and_keeps_its_ranges():
    n = len(CFG["families"])
    assert dr.draw(9) == dr.draw(9) and dr.draw(9) != dr.draw(9 + n)
    assert dr.draw(9, 1) != dr.draw(9, 2)
    for i in range(6 * n):
        d = dr.draw(i, cfg=CFG)
        assert d["family"] == CFG["families"][i % n]
        for o in d["objects"]:
            assert dr.corners(o)[:, 1].min() >= CFG["region"]["wall_gap_m"] - 1e-9
            if o["role"] == "target" and o["shape"] == "plate":
                w, h = o["size"]
                assert 0.2 <= w <= 1.2 and 0.2 <= h <= 1.8
        if d["family"] == "occluders":  # the plate lies between the wall and the target
            target, occ = d["objects"]
            u = np.asarray(target["centre"]) / np.linalg.norm(target["centre"])
            assert (dr.corners(occ) @ u).max() < (dr.corners(target) @ u).min()
        if d["family"] == "bins":
            assert 16e-12 <= d["noise"]["photons"]["tdc_bin_s"] <= 1.5e-9
        if d["family"] == "clutter":
            assert {o["role"] for o in d["objects"]} == {"target", "furniture"}


def _cheap(cfg):
    """Three families (walls, records, occluders) on three spots and coarse facets: seconds."""
    cfg = copy.deepcopy(cfg)
    cfg["families"] = ["walls", "records", "occluders"]
    cfg["facet_size_m"] = 0.05
    for f in cfg["families"]:
        cfg[f]["layouts"] = ["triangle"]
        cfg[f]["shapes"] = ["plate"]
    return cfg


def test_a_run_through_the_command_line_writes_the_tables_and_counts_a_wrong_answer(
        tmp_path, monkeypatch, capsys):
    cfg = _cheap(CFG)
    monkeypatch.setattr(dr, "config", lambda: copy.deepcopy(cfg))
    real = run.cli

    def wrong_for_draw_1(argv):  # draw 1's answer moved 0.5 m along the file's X
        status, out, err = real(argv)
        if argv[0] == "locate" and "draw-1" in str(argv[1]):
            answer = json.loads(out)
            for t in answer["targets"]:
                t["position"][0] += 0.5
            out = json.dumps(answer)
        return status, out, err
    monkeypatch.setattr(run, "cli", wrong_for_draw_1)
    assert cli.main(["reproduce", "scenarios", "--draws", "3", "--out", str(tmp_path)]) == 0
    with open(tmp_path / "scenarios.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["family"] for r in rows] == cfg["families"]
    assert ROW_COLUMNS <= set(rows[0])
    assert all(r["exit"] == "0" and r["command"] == "locate" for r in rows)
    assert rows[1]["failed"] == "True" and "error" in rows[1]["why"]
    assert float(rows[1]["error_m"]) > 0.35  # the 0.5 m push, less what it started off by
    with open(tmp_path / "scenarios-summary.csv", newline="") as f:
        summ = list(csv.DictReader(f))
    assert SUMMARY_COLUMNS <= set(summ[0]) and summ[-1]["family"] == "all"
    assert int(summ[-1]["failures"]) == sum(r["failed"] == "True" for r in rows) >= 1
    page = (tmp_path / "scenarios.md").read_text()
    for section in ("## Overall and per family", "## By sub-range",
                    "## Every failure, worst first"):
        assert section in page
    assert "| 1 | records |" in page  # the forced failure is listed
    assert not (tmp_path / "scenarios-progress.jsonl").exists()
    assert "failure rate" in capsys.readouterr().out


def _locate(answer_targets, truths, lit=None, status=0, warnings=(), said=(), shadowed=()):
    out = json.dumps({"targets": [{"position": p} for p in answer_targets],
                      "warnings": list(warnings), "shadowed": list(shadowed)}) \
        if status == 0 else ""
    shares = [1.0] * len(truths) if lit is None else lit
    return score.locate(CFG, status, out, list(said), (np.asarray(truths, float), shares))


T = [[1.0, 0.0, 3.0], [-1.0, 0.2, 2.0]]


def test_the_failure_rule_on_located_answers():
    good = _locate([T[1], [1.05, 0.0, 3.0]], T)
    assert not good["failed"] and good["right_k"] and good["error_m"] == pytest.approx(0.05)
    off = _locate([T[1], [1.2, 0.0, 3.0]], T)
    assert off["failed"] and "error 0.200 m" in off["why"] and not off["warned"]
    missed = _locate([T[0]], T, warnings=["the data hold more"])
    assert missed["failed"] and math.isinf(missed["error_m"]) and not missed["right_k"]
    assert missed["warned"]
    extra = _locate([T[0], T[1], [0.0, 0.0, 4.0]], T)
    assert extra["failed"] and not extra["right_k"] and extra["error_m"] == 0.0
    shadowed = _locate([T[0]], T, lit=[1.0, 0.0])  # the second is in a shadow
    assert shadowed["failed"] and "shadowed" in shadowed["why"] and shadowed["right_k"]
    said = _locate([T[0]], T, lit=[1.0, 0.0], warnings=["a second target may be hidden"])
    assert said["failed"] and not said["in_declared_shadow"]  # words excuse nothing


def _shadow(centre, apex=(0.0, 0.0, 0.0)):
    """A declared shadow: a 0.4 m square plate (file frame, facing the apex along Z)."""
    return {"target": 1, "apex": list(apex), "box": {"centre": list(centre), "axes": [
        [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "half_m": [0.2, 0.2, 0.0]}}


def test_a_shadowed_truth_is_excused_only_inside_a_declared_shadow():
    """The truth at (-1, 0.2, 2) from an apex at the origin: a plate half-way there hides it;
    one beside that way, or behind the truth, does not."""
    between = _locate([T[0]], T, lit=[1.0, 0.0], shadowed=[_shadow([-0.5, 0.1, 1.0])])
    assert not between["failed"] and between["in_declared_shadow"]
    for centre in ([0.5, 0.1, 1.0], [-1.5, 0.3, 3.0]):
        elsewhere = _locate([T[0]], T, lit=[1.0, 0.0], shadowed=[_shadow(centre)])
        assert elsewhere["failed"] and "declared shadow" in elsewhere["why"]
    lit_missed = _locate([T[0]], T, shadowed=[_shadow([-0.5, 0.1, 1.0])])
    assert lit_missed["failed"] and "lit target missed" in lit_missed["why"]
    refused = _locate([], T, status=2, said=["nlos-cl: h5: no such file. Fix: ..."])
    assert refused["failed"] and refused["exit"] == "2" and refused["warned"]
    crashed = _locate([], T, status="crash")
    assert crashed["failed"] and crashed["exit"] == "crash" and not crashed["warned"]


def _frames(tracks_per_frame):
    return "\n".join(json.dumps({"frame": k, "tracks": [
        {"id": i + 1, "status": s, "position": p} for i, (p, s) in enumerate(ts)]})
        for k, ts in enumerate(tracks_per_frame))


def test_the_failure_rule_on_tracked_sequences():
    """Scored frames 2-4 of five: one mover at X = k / 10; a static track does not count."""
    truths = {k: (np.array([[k / 10, 0.0, 3.0]]), [1.0]) for k in (2, 3, 4)}
    near = [[([k / 10 + 0.02, 0.0, 3.0], "confirmed"), ([2.0, 0.0, 4.0], "tentative")]
            for k in range(5)]
    ok = score.track(CFG, 0, _frames(near), [], truths)
    assert not ok["failed"] and ok["found"] == 1 and ok["error_m"] == pytest.approx(0.02)
    stuck = [[([0.0, 0.0, 3.0], "confirmed"), ([2.0, 0.0, 4.0], "confirmed")]
             for _ in range(5)]  # a track on the start, one on clutter: both confirmed
    bad = score.track(CFG, 0, _frames(stuck), ["nlos-cl: warning: x"], truths)
    assert bad["failed"] and bad["found"] == 2 and not bad["right_k"]
    assert bad["error_m"] == pytest.approx(0.3) and bad["warned"]


def test_only_runs_one_familys_draws_among_the_first_n(tmp_path, monkeypatch):
    """`--only occluders --draws 3`: the one occluder draw a full 3-draw run makes (index 2),
    nothing else; a family that does not exist is refused naming the option."""
    cfg = _cheap(CFG)
    monkeypatch.setattr(dr, "config", lambda: copy.deepcopy(cfg))
    assert cli.main(["reproduce", "scenarios", "--draws", "3", "--only", "occluders",
                     "--out", str(tmp_path)]) == 0
    with open(tmp_path / "scenarios.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["index"], r["family"]) for r in rows] == [("2", "occluders")]
    assert "--only occluders" in (tmp_path / "scenarios.md").read_text()
    with pytest.raises(Exception, match="--only"):
        rp.run("scenarios", rp.Settings.make(), tmp_path, draws=3, only=["walk"])
