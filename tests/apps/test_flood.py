"""The flood study's pieces (nlos_cl/apps/reproduce/flood/study.py): the multizone sensor's geometry,
the pose fit, the flood simulation's paths, and one draw end to end. The dataset check reads
../shared/realdata and skips where it is absent."""
import math
from pathlib import Path

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.apps.reproduce.flood import study as fl
from nlos_cl.core.constants import SPEED_OF_LIGHT as C
from nlos_cl.ops.forward import facet_paths

CFG = fl.config()
SENSOR = fl.MultizoneSensor.from_config(CFG["sensor"])
WALK = (Path(__file__).resolve().parents[3] / "shared" / "realdata" / "consumer-nlos"
        / "st_spad_person_tracking" / "volume_000000.npz")


def test_zone_spots_are_the_one_sample_flood_and_lie_on_the_wall():
    spots = SENSOR.zone_spots()
    points, weights = SENSOR.flood(1)
    assert spots.shape == (16, 3) and np.all(spots[:, 1] == 0.0)
    assert np.allclose(points, spots, atol=1e-12)
    assert np.all(weights > 0) and math.isclose(weights.sum(), 1.0)
    # the zone's own spot starts its light when the capture's t = 0 does
    assert np.allclose(np.diag(SENSOR.path_offsets(points, spots)), 0.0, atol=1e-12)


def _cell_solid_angles(fov_rad, n):
    """Exact solid angles of an n x n grid uniform in angle over a square field: a rectangle
    [x1, x2] x [y1, y2] of the plane z = 1 subtends F(x2, y2) - F(x1, y2) - F(x2, y1) +
    F(x1, y1), F(x, y) = atan(x y / sqrt(1 + x^2 + y^2))."""
    t = np.tan(np.linspace(-fov_rad / 2, fov_rad / 2, n + 1))
    x, y = t[None, :], t[:, None]
    F = np.arctan(x * y / np.sqrt(1 + x ** 2 + y ** 2))
    return (F[1:, 1:] - F[1:, :-1] - F[:-1, 1:] + F[:-1, :-1]).ravel()


@pytest.mark.parametrize("sub", [1, 4])
def test_flood_weights_are_solid_angles(sub):
    """Each laser point carries its cell's share of the field's solid angle (the midpoint
    rule against the exact cells: within 1 %); the whole field of a 45 deg square pyramid is
    4 asin(sin^2 22.5 deg) sr."""
    n = SENSOR.zones * sub
    exact = _cell_solid_angles(SENSOR.fov_rad, n)
    assert exact.sum() == pytest.approx(4 * math.asin(math.sin(SENSOR.fov_rad / 2) ** 2))
    _, weights = SENSOR.flood(sub)
    # flood's points run over the fine grid row by row, as the exact cells do
    assert np.allclose(weights, exact / exact.sum(), rtol=0.01, atol=0)


def test_fit_recovers_a_known_pose():
    truth = fl.MultizoneSensor([0.3, 1.1, 0.2], fl.FACING_WALL + [0.1, -0.2, 0.3],
                               math.radians(40.0))
    fitted, rms = fl.fit_sensor(truth.zone_spots())
    assert rms < 1e-6
    assert np.linalg.norm(fitted.position - truth.position) < 1e-4
    assert math.degrees(fitted.fov_rad) == pytest.approx(40.0, abs=1e-3)


def test_fit_refuses_the_wrong_number_of_spots():
    with pytest.raises(nl.InputError, match="spots"):
        fl.fit_sensor(np.zeros((9, 3)))


@pytest.mark.skipif(not WALK.is_file(), reason="../shared/realdata/consumer-nlos is absent")
def test_the_configured_pose_is_the_datasets():
    """flood.yaml's pose is fit_sensor's on the walk's own wall spots (the reader's frame),
    and the fitted field of view is the VL53L8 datasheet's 45 deg."""
    from nlos_cl.io.datasets.consumer_nlos import TO_INTERNAL
    with np.load(WALK) as f:
        spots = f["pt_cloud"] @ TO_INTERNAL.T
    spots[:, 1] = 0.0
    fitted, rms = fl.fit_sensor(spots)
    assert rms < 0.01
    assert np.linalg.norm(fitted.position - SENSOR.position) < 1e-3
    assert math.degrees(fitted.fov_rad) == pytest.approx(45.0, abs=0.5)
    assert np.abs(SENSOR.zone_spots() - spots).max() < 0.01


def _mean_path(h):
    """Each zone's signal-weighted mean hidden path (bin centres; the pulse is symmetric)."""
    centres = C * h.time_axis.centres()
    return (h.data * centres).sum(axis=1) / h.data.sum(axis=1)


@pytest.mark.parametrize("flood", [False, True])
def test_simulated_paths_are_the_sensors(runtime, flood):
    """A small plate: each zone's mean path in the simulated histograms is the one computed
    here from the facets (confocal 2 |p - d|; flood |s - l| - |s - d| + |l - p| + |p - d|
    weighted by each laser point's power and geometric weight), within a tenth of a bin."""
    cfg = dict(CFG, samples_per_zone=2)
    target = nl.Target(nl.rectangle(0.1, 0.1, centre=(0.6, 0.9, 0.05), normal=(0.0, -1.0, 0.0),
                                    cell_m=0.02))
    h = fl.simulate_zones(target, SENSOR, cfg, flood=flood, backend=runtime)
    spots = SENSOR.zone_spots()
    f = target.facets(cfg["facet_m"])
    if flood:
        points, weights = SENSOR.flood(2)
        offsets = SENSOR.path_offsets(points, spots)
    else:
        points, weights, offsets = spots, np.ones(len(spots)), np.zeros((len(spots), 16))
    num, den = np.zeros(16), np.zeros(16)
    for k, (laser, w) in enumerate(zip(points, weights)):
        lasers = spots if not flood else np.tile(laser, (16, 1))
        path, g = facet_paths(f.centres, f.normals, f.areas, spots, lasers)
        if not flood:  # confocal: row d is zone d's own laser only
            path, g = path[k:k + 1], g[k:k + 1]
            rows = [k]
        else:
            rows = slice(None)
        path = path + (offsets[k][:, None] if flood else 0.0)
        num[rows] += w * (g * path).sum(axis=1)
        den[rows] += w * g.sum(axis=1)
    assert np.abs(_mean_path(h) - num / den).max() < 0.1 * C * h.time_axis.dt_s


def test_a_draw_runs_both_ways_and_is_reproducible(runtime):
    """Draw 0 of the study, its row's errors finite; the same index gives the same scene,
    another index another; every centre in the region and clear of the sensor."""
    row = fl.run_draw(fl.draw(0, CFG), CFG, SENSOR, backend=runtime)
    for key in ("confocal_error_m", "flood_error_m", "flood_shift_m", "mirror_surface_m"):
        assert math.isfinite(row[key]), key
    assert {row[f"{n}_estimator"] for n in fl.READINGS} == {"paper"}
    assert row["confocal_shift_m"] == 0.0
    assert fl.draw(3, CFG) == fl.draw(3, CFG) and fl.draw(3, CFG) != fl.draw(4, CFG)
    t = CFG["targets"]
    for i in range(50):
        c = np.array(fl.draw(i, CFG)["centre"])
        assert all(lo <= v <= hi for v, (lo, hi) in zip(c, (t["x"], t["y"], t["z"])))
        assert np.linalg.norm(c - SENSOR.position) >= t["min_from_sensor_m"]
    stats = fl.summary([row, row])
    assert stats["flood_shift_m"]["median"] == pytest.approx(row["flood_shift_m"], abs=1e-4)


def test_reproduce_flood_writes_the_page_and_its_rows(tmp_path):
    """`nlos-cl reproduce flood` (not part of 'all'): one draw through the CLI, the rows in
    OUT/flood.csv and beside --doc's page, which names the command that wrote it."""
    import csv
    import subprocess
    import sys
    from nlos_cl.apps import reproduce as rp
    assert "flood" in rp.EXPERIMENTS and "flood" not in rp.PAPER_EXPERIMENTS
    out, doc = tmp_path / "out", tmp_path / "doc" / "flood.md"
    proc = subprocess.run([sys.executable, "-m", "nlos_cl.apps.cli", "reproduce", "flood",
                           "--quick", "--draws", "1", "--out", str(out), "--doc", str(doc)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    page = doc.read_text()
    assert page == (out / "flood.md").read_text()
    assert page.startswith("# A multizone sensor's flood, read as confocal")
    assert "Generated by `nlos-cl reproduce flood --quick --draws 1` on" in page
    assert "## What the numbers say" in page
    for table in (out / "flood.csv", doc.with_name("flood.csv")):
        with open(table) as f:
            rows = list(csv.DictReader(f))
        assert len(rows) == 1 and math.isfinite(float(rows[0]["flood_shift_m"]))
