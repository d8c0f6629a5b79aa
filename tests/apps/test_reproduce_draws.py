"""`nlos-cl reproduce draws`: the scene generator is a pure function of (family, index,
master seed) whose draws keep draws.yaml's constraints, and a --quick run writes the page and
the CSVs with the report's columns. Crossings: the paths cross inside the region, timed as
drawn; the per-draw measures (ids, swaps, merges) count what they say; a short sequence runs
through `reproduce draws --only crossings`."""
import copy
import csv
import math
from pathlib import Path

import numpy as np
import pytest

from nlos_cl.apps import reproduce as rp
from nlos_cl.apps.reproduce.common import Settings
from nlos_cl.apps.reproduce.draws import cross_run as draws_cross_run, experiment as draws
from nlos_cl.apps.reproduce.draws import report as draws_report, run as draws_run
from nlos_cl.simulation.draws import crossings as cg, families as g
from nlos_cl.core.errors import InputError

CFG = g.config()
N = 40  # draws per family checked (pure and fast: no simulation)


def test_draws_is_an_experiment_but_not_part_of_all():
    assert "draws" in rp.EXPERIMENTS and "draws" not in rp.PAPER_EXPERIMENTS


@pytest.mark.parametrize("family", g.FAMILIES)
def test_a_draw_is_a_pure_function_of_its_seed(family):
    assert g.draw(family, 7) == g.draw(family, 7)
    assert g.draw(family, 7, 5) == g.draw(family, 7, 5, CFG)
    assert g.draw(family, 7) != g.draw(family, 8)
    assert g.draw(family, 7, 5) != g.draw(family, 7, 6)
    assert g.draw(family, 3)["master_seed"] == CFG["master_seed"]


def test_a_draw_refuses_unknown_families_and_bad_indices():
    with pytest.raises(InputError, match="family"):
        g.draw("none", 0)
    with pytest.raises(InputError, match="index"):
        g.draw("one", -1)


def _inside(value, pair):
    return pair[0] - 1e-9 <= value <= pair[1] + 1e-9


def _check_target(t, spots, collinear_axis):
    reg, shapes = CFG["region"], CFG["shapes"]
    c = np.asarray(t["centre"])
    assert _inside(c[0], reg["x"]) and _inside(c[1], reg["y"]) and _inside(c[2], reg["z"])
    if collinear_axis is not None:  # the centre on the plane collinear spots search
        assert c[collinear_axis] == 0.0
    p = shapes[t["shape"]]
    if t["shape"] in ("plate", "box"):
        assert all(_inside(v, p["side_m"]) or _inside(v, CFG["families"]["multi"]["plate_side_m"])
                   for v in t["size"])
        assert abs(t["yaw_deg"]) <= reg["yaw_deg"] + 1e-9
        assert abs(np.linalg.norm(t["normal"]) - 1) < 1e-5 and t["normal"][2] == 0
    if t["shape"] == "plate":  # it faces O and every spot: it returns light to each
        assert g.facing_cos(np.asarray(t["normal"]), c, spots) >= reg["min_facing_cos"] - 1e-6
    if t["shape"] in ("sphere", "cylinder"):
        assert _inside(t["radius_m"], p["radius_m"])
    if t["shape"] == "cylinder":
        assert _inside(t["height_m"], p["height_m"])
    assert c[1] - g.bounding_radius(t) > 0.3  # well clear of the wall


def _check_layout(lay, family):
    wall = CFG["wall"]
    spots = np.asarray(lay["spots"])
    assert spots.shape[1] == 3 and np.all(spots[:, 1] == 0)
    assert np.linalg.norm(spots, axis=1).min() >= wall["min_from_laser_m"] - 1e-9
    if lay["kind"] != "line":
        assert np.all((spots[:, 0] >= wall["x"][0]) & (spots[:, 0] <= wall["x"][1]))
        assert g._spread(np.vstack([np.zeros(3), spots])) >= wall["min_spread_m"]
    if family == "multi":
        assert len(spots) >= CFG["families"]["multi"]["min_spots"]
    if lay["kind"] == "spad":
        assert 16 <= len(spots) <= 64
    if lay["kind"] == "circle":
        assert 6 <= len(spots) <= 9
    return spots


LOCATED = [f for f in g.FAMILIES if f != "crossings"]  # one frame each, located


@pytest.mark.parametrize("family", LOCATED)
def test_draws_respect_the_constraints(family):
    kinds, shapes = set(), set()
    for i in range(N):
        d = g.draw(family, i)
        lay = d["layout"]
        spots = _check_layout(lay, family)
        kinds.add(lay["kind"])
        axis = None
        if lay["collinear"]:
            axis = 2 if abs(math.cos(math.radians(lay["angle_deg"]))) > 0.5 else 0
        for t in d["targets"]:
            _check_target(t, spots, axis)
            shapes.add(t["shape"])
        assert _inside(d["snr_db"], CFG["snr_db"])
        if family == "multi":
            assert len(d["targets"]) == CFG["families"]["multi"]["targets"][i % 2]
            centres = np.array([t["centre"] for t in d["targets"]])
            gaps = np.linalg.norm(centres[:, None] - centres[None], axis=2)
            assert gaps[np.triu_indices(len(centres), 1)].min() >= 0.8
        else:
            assert len(d["targets"]) == 1
        if family == "mismatch":
            assert d["mismatch"]["kind"] == CFG["families"]["mismatch"]["subfamilies"][i % 5]
        if family == "counts":
            c, fam_c = d["counting"], CFG["families"]["counts"]
            assert _inside(c["signal_photons"], fam_c["signal_photons"])
            assert _inside(c["ambient_rate_hz"], fam_c["ambient_rate_hz"])
            assert _inside(c["tdc_ps"], fam_c["tdc_ps"]) and isinstance(c["tdc_ps"], int)
    fam = CFG["families"]["one" if family in ("mismatch", "counts") else family]
    assert kinds == set(fam["layouts"]) and shapes == set(fam["shapes"])  # every one is drawn
    if family == "closed":
        assert "plate" not in shapes


def test_errors_are_matched_by_assignment_and_missed_targets_fail():
    truths = np.array([[1.0, 2.0, 0.0], [2.0, 2.0, 0.0]])
    found = [np.array([2.1, 2.0, 0.0]), np.array([1.0, 2.2, 0.0])]
    assert np.allclose(draws_run.matched_errors(found, truths), [0.2, 0.1])
    errors = draws_run.matched_errors(found[:1], truths)
    assert math.isnan(errors[0]) and errors[1] == pytest.approx(0.1)
    rows = [{"error_m": e, "k_found": 1, "k_true": 1, "seconds": 1.0, "warned": w}
            for e, w in ((0.01, False), (0.2, True), (math.nan, False), (0.3, False))]
    st = draws_report.stats(rows, 0.15)
    assert st["failure_rate"] == 0.75 and st["unwarned_failures"] == 2
    assert st["worst_m"] == math.inf and st["median_m"] == pytest.approx(0.25)


def test_a_quick_run_writes_the_report(tmp_path):
    s = Settings.make(quick=True)
    result = rp.run("draws", s, tmp_path, only=["one"])[0]
    assert {r["estimator"] for r in result.rows} == {"paper", "default"}
    page = (tmp_path / "draws.md").read_text()
    for column in ("median (m)", "p90 (m)", "worst (m)", "failures (> 0.15 m)",
                   "beyond 0.15 m without a warning", "K right"):
        assert column in page
    # the targets' checks go to --json ("goals", for the session's note), not on the page
    assert "| check |" not in page and result.summary["goals"]
    assert "Generated by `nlos-cl reproduce draws --quick --only one`" in page
    with open(tmp_path / "draws.csv") as f:
        rows = list(csv.DictReader(f))
    assert {"family", "index", "master_seed", "error_m", "warned", "k_found", "fitted",
            "closed_gain"} <= set(rows[0])
    fitted = {r["estimator"]: r["fitted"] for r in rows}
    assert fitted["paper"] == "-" and fitted["default"] in {"plate", "box", "ellipsoid",
                                                            "cylinder"}
    # a row's (family, index, master seed) draws its scene again
    d = g.draw(rows[0]["family"], int(rows[0]["index"]), int(rows[0]["master_seed"]))
    assert draws_run.describe(d)["truths"] == rows[0]["truths"]
    with pytest.raises(InputError, match="--only"):
        rp.run("draws", s, tmp_path, only=["nothing"])


def test_draws_in_worker_processes_are_those_of_one_process():
    """--jobs 2: the same rows in the same order, times aside (a draw is a pure function of
    its family, index and master seed)."""
    s = Settings.make(quick=True)
    timed = ("seconds", "sim_s")
    one = draws.run_rows(["one"], 2, s, 2201, g.config())
    two = draws.run_rows(["one"], 2, s, 2201, g.config(), jobs=2)
    assert [{k: v for k, v in r.items() if k not in timed} for r in two] == \
        [{k: v for k, v in r.items() if k not in timed} for r in one]
    with pytest.raises(InputError, match="--jobs"):
        draws.draws(s, Path("unused"), only=["one"], jobs=0)


FAM = CFG["families"]["crossings"]


def test_crossing_draws_cross_inside_the_region_nearly_together():
    reg = CFG["region"]
    span = (FAM["frames"] - 1) / FAM["fps"]
    kinds = set()
    for i in range(N):
        d = g.draw("crossings", i)
        spots = _check_layout(d["layout"], "crossings")
        kinds.add(d["layout"]["kind"])
        assert len(spots) == FAM["spots"] and d["frames"]["frames"] == FAM["frames"]
        assert _inside(d["snr_db"], CFG["snr_db"]) and len(d["targets"]) == 2
        c, paths = d["crossing"], [np.asarray(t["path"]) for t in d["targets"]]
        assert cg.segments_cross(*paths)
        for t, path, f in zip(d["targets"], paths, c["fractions"]):
            assert t["shape"] == "plate" and all(_inside(v, FAM["plate_side_m"])
                                                 for v in t["size"])
            assert t["centre"] == t["path"][0] and path[0, 2] == path[1, 2]  # level walks
            for p in path:  # both ends (so all of a straight path) inside, facing every spot
                assert _inside(p[0], reg["x"]) and _inside(p[1], reg["y"])
                assert _inside(p[2], reg["z"])
                assert g.facing_cos(np.asarray(t["normal"]), p, spots) >= \
                    reg["min_facing_cos"] - 1e-6
            assert _inside(np.linalg.norm(path[1] - path[0]), FAM["length_m"])
            assert _inside(f, FAM["crossing_fraction"])
            # at its fraction of the way (and of the time) each target is on the crossing
            assert np.allclose(path[0, :2] + f * (path[1, :2] - path[0, :2]),
                               c["crossing_xy"], atol=1e-5)
        ways = [(p[1] - p[0])[:2] / np.linalg.norm((p[1] - p[0])[:2]) for p in paths]
        turn = math.degrees(math.acos(np.clip(np.dot(*ways), -1, 1)))
        assert _inside(turn, FAM["turn_deg"]) and abs(turn - abs(c["turn_deg"])) < 1e-3
        # they pass X one just after the other: no closer than their half widths plus the gap
        half = sum(0.5 * t["size"][0] for t in d["targets"])
        assert _inside(c["closest_m"] - half, FAM["gap_m"])
        assert cg.closest_approach(paths) >= c["closest_m"] - 1e-5
        assert abs(c["fractions"][1] - c["fractions"][0]) * span == \
            pytest.approx(abs(c["offset_s"]), abs=1e-5)
    assert kinds == set(FAM["layouts"])


def test_segments_cross_and_closest_approach():
    a, b = [[0, 0], [2, 2]], [[0, 2], [2, 0]]
    assert cg.segments_cross(a, b) and not cg.segments_cross(a, [[1, 3], [3, 1.5]])
    assert cg.closest_approach([a, b]) == pytest.approx(0.0, abs=1e-9)
    # the two walk at the same time: a parallel pair keeps its gap, a head-on pair meets midway
    assert cg.closest_approach([a, [[0, 3], [2, 5]]]) == pytest.approx(3.0)
    assert cg.closest_approach([[[0, 0], [2, 0]], [[2, 1], [0, 1]]]) == pytest.approx(1.0)


def _frames(ids_per_frame, truths):
    """Tracked frames: per frame {id: truth index (its position) or an (x, y, z) point}."""
    return [{"tracks": {i: np.asarray(truths[w] if isinstance(w, int) else w, float)
                        for i, w in ids.items()},
             "measured": [0] * len(ids), "truths": np.asarray(truths, float)}
            for ids in ids_per_frame]


def test_crossing_measures_count_ids_swaps_and_merges():
    truths = [[1.0, 2.0, 0.0], [2.0, 3.0, 0.0]]
    kept = draws_cross_run.measure(_frames([{1: 0, 2: 1}] * 10, truths), 5, 0.15)
    assert kept["ids_ok"] and (kept["ids_a"], kept["ids_b"]) == ("1", "2")
    assert kept["rms_m"] == 0 and kept["swaps"] == kept["merged_frames"] == 0
    assert kept["births"] == 2 and kept["lost"] == 0
    swapped = draws_cross_run.measure(_frames([{1: 0, 2: 1}] * 7 + [{1: 1, 2: 0}] * 3, truths),
                                      5, 0.15)
    assert not swapped["ids_ok"] and swapped["ids_a"] == "1 2" and swapped["swaps"] == 2
    merged = draws_cross_run.measure(
        _frames([{1: 0, 2: 1}] * 7 + [{1: (1.5, 2.5, 0.0)}] * 3, truths), 5, 0.15)
    assert not merged["ids_ok"] and merged["merged_frames"] == 3 and merged["lost"] == 1
    assert merged["under_two_measured"] == 3 and merged["frames_beyond"] == 6
    gone = draws_cross_run.measure(_frames([{1: 0, 2: 1}] * 9 + [{}], truths), 5, 0.15)
    assert not gone["ids_ok"] and gone["missing_frames"] == 2 and math.isnan(gone["rms_m"])


def test_rows_of_two_kinds_share_one_csv():
    rows = draws.uniform([{"family": "one", "error_m": 0.1}, {"family": "crossings", "ids_ok": 1}])
    assert [list(r) for r in rows] == [["family", "error_m", "ids_ok"]] * 2
    assert rows[0]["ids_ok"] == "" and rows[1]["error_m"] == ""


def test_a_short_crossing_run_writes_its_section(tmp_path, monkeypatch):
    """One crossing draw of 8 frames (the full family's 50 take ~30 s here) through
    `reproduce draws --quick --only crossings`."""
    short = copy.deepcopy(CFG)
    short["families"]["crossings"]["frames"] = 8
    monkeypatch.setattr(g, "config", lambda: short)
    result = rp.run("draws", Settings.make(quick=True), tmp_path, only=["crossings"])[0]
    (row,) = result.rows
    assert row["family"] == "crossings" and row["frames"] == 8 and not row["failed"]
    assert len(row["live"].split()) == 8 and row["frames_per_s"] > 0
    assert math.isfinite(row["rms_m"]) and row["births"] >= 1
    assert {goal["goal"] for goal in result.summary["goals"]} == {
        "crossings: one track id per target after frame 5",
        "crossings: RMS (worse target) <= 0.05 m", "crossings: tracking frames/s (median)"}
    page = (tmp_path / "draws.md").read_text()
    assert "## Crossings (tracked sequences)" in page and "## By layout" not in page
    with open(tmp_path / "draws.csv") as f:
        (written,) = list(csv.DictReader(f))
    assert written["ids_ok"] == str(row["ids_ok"]) and written["index"] == "0"
    assert cg.segments_cross(*[t["path"] for t in g.draw("crossings", 0, cfg=short)["targets"]])


def test_a_counts_draw_is_photon_counts_with_its_drawn_signal():
    """The counts family's frame: whole numbers in the drawn TDC bins, whose mean total per
    detector is the drawn signal photons plus the dark and ambient counts' expectation (at
    the pulses that signal needs), within 5 Poisson sd."""
    from nlos_cl.physics.noise import PhotonCounter
    from nlos_cl.simulation.draws import scenes
    d = g.draw("counts", 3)
    clean, _ = scenes.simulate(d, Settings.make(quick=True))
    frame = scenes.noisy(clean, d)
    c = d["counting"]
    assert np.array_equal(frame.data, np.round(frame.data)) and frame.data.min() >= 0
    assert abs(frame.time_axis.dt_s - c["tdc_ps"] * 1e-12) < 1e-18
    n_det, n_bins = frame.data.shape
    quiet = PhotonCounter(n_pulses=1.0, dark_count_rate_hz=0.0, ambient_rate_hz=0.0,
                          tdc_bin_s=c["tdc_ps"] * 1e-12)
    pulses = c["signal_photons"] / np.mean(quiet.expected_counts(clean).data.sum(axis=1))
    rate = c["ambient_rate_hz"] + PhotonCounter().dark_count_rate_hz
    expected = c["signal_photons"] + rate * frame.time_axis.dt_s * n_bins * pulses
    per_detector = frame.data.sum() / n_det
    assert abs(per_detector - expected) < 5 * np.sqrt(expected / n_det), (per_detector, expected)
