"""`nlos-cl reproduce draws`: the scene generator is a pure function of (family, index,
master seed) whose draws keep draws.yaml's constraints, and a --quick run writes the page and
the CSVs with the report's columns."""
import csv
import math

import numpy as np
import pytest

from nlos_cl.apps import reproduce as rp
from nlos_cl.apps.reproduce import draws_gen as g
from nlos_cl.apps.reproduce import draws_report, draws_run
from nlos_cl.apps.reproduce.common import Settings
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


@pytest.mark.parametrize("family", g.FAMILIES)
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
    fam = CFG["families"]["one" if family == "mismatch" else family]
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
                   "beyond 0.15 m without a warning", "K right", "| goal |"):
        assert column in page
    assert "Generated by `nlos-cl reproduce draws --quick --only one`" in page
    with open(tmp_path / "draws.csv") as f:
        rows = list(csv.DictReader(f))
    assert {"family", "index", "master_seed", "error_m", "warned", "k_found"} <= set(rows[0])
    # a row's (family, index, master seed) draws its scene again
    d = g.draw(rows[0]["family"], int(rows[0]["index"]), int(rows[0]["master_seed"]))
    assert draws_run.describe(d)["truths"] == rows[0]["truths"]
    with pytest.raises(InputError, match="--only"):
        rp.run("draws", s, tmp_path, only=["nothing"])
