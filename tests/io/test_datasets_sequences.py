"""Measured datasets that are sequences (nlos_cl.io.datasets: consumer-nlos) through
`nlos-cl convert` and `nlos-cl track`: a committed fixture (six frames of the consumer-nlos walk,
MIT, tests/fixtures/consumer_nlos/SOURCE.md), then the full folder in ../shared/realdata where
present (skipped otherwise)."""
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.apps.cli import main as cli
from nlos_cl.io.datasets import detect, read_dataset
from nlos_cl.tracking import read_sequence

FIXTURE = Path(__file__).resolve().parents[1] / "fixtures" / "consumer_nlos"
REAL = Path(__file__).resolve().parents[3] / "shared" / "realdata"
WALK = REAL / "consumer-nlos" / "st_spad_person_tracking"


def npz(path):
    with np.load(path) as f:
        return {k: f[k] for k in f}


def converted(tmp_path, src=FIXTURE, *extra):
    out = tmp_path / "walk.h5"
    assert cli(["convert", str(src), "--out", str(out), *extra]) == 0
    return read_sequence(out)


def test_consumer_nlos_fixture_converts_to_a_confocal_sequence(tmp_path, capsys):
    before = {p.name: p.read_bytes() for p in FIXTURE.iterdir()}
    assert detect(FIXTURE) == "consumer-nlos"
    seq = converted(tmp_path)
    assert "6 frames at 14 Hz, each 16 histograms x 128 bins of 250 ps, confocal" in \
        capsys.readouterr().out
    assert {p.name: p.read_bytes() for p in FIXTURE.iterdir()} == before  # untouched
    assert len(seq) == 6 and np.allclose(seq.t_s, np.arange(6) / 14.0)
    files = sorted(FIXTURE.glob("volume_*.npz"))
    for frame, path in zip(seq, files):
        raw = npz(path)
        h = frame.histograms
        assert h.paired and np.array_equal(h.laser_spots, h.detector_spots)
        np.testing.assert_allclose(h.data, raw["hists"], rtol=1e-6)  # float32 in the file
        assert h.time_axis.dt_s == pytest.approx(250e-12) and h.time_axis.t0_s == 0
        assert frame.truths is None  # the particles are an estimate, not a truth
    ref = np.array(seq.metadata["reference_positions"])
    means = np.array([npz(p)["particles"].astype(np.float64).mean(axis=0) for p in files])
    np.testing.assert_allclose(ref, means, atol=1e-9)
    assert seq.metadata["dataset_format"] == "consumer-nlos" and seq.metadata["fps"] == 14.0


def test_consumer_nlos_geometry_wall_and_hidden_side():
    frames, meta = read_dataset(FIXTURE)
    h = frames[0][1]
    pt = npz(FIXTURE / "volume_000000.npz")["pt_cloud"]
    # ours (x, y, z) = (-X, Z, Y) of theirs, the spots put on the wall plane (<= 1.2 cm moved)
    assert np.all(h.detector_spots[:, 1] == 0)
    np.testing.assert_allclose(h.detector_spots[:, [0, 2]], np.column_stack([-pt[:, 0],
                                                                             pt[:, 1]]))
    assert meta["wall_offset_max_m"] == pytest.approx(np.abs(pt[:, 2]).max())
    assert meta["wall_offset_max_m"] < 0.012
    from nlos_cl.io.ytal.frames import YTAL
    hidden = YTAL.to_internal(np.array(meta["reference_positions"]))
    assert np.all(hidden[:, 1] > 0.3)  # their estimate lies on our hidden side, y > 0
    # the returns (non-zero bins 15 .. 53, README) are paths of 1.1 .. 4 m: in front of the wall
    path = h.hidden_path_axis()[0][h.data.sum(axis=0) > 0]
    assert 1.0 < path.min() and path.max() < 4.1


def test_consumer_nlos_options_and_refusals(tmp_path, capsys):
    seq = converted(tmp_path, FIXTURE, "--fps", "10", "--dt-ps", "200")
    assert np.allclose(seq.t_s, np.arange(6) / 10.0)
    assert seq[0].histograms.time_axis.dt_s == pytest.approx(200e-12)
    assert cli(["convert", str(FIXTURE), "--out", str(tmp_path / "b.h5"), "--width", "1"]) == 2
    assert "--width: is not an option of the consumer-nlos format" in capsys.readouterr().err
    bad = tmp_path / "bad"
    bad.mkdir()
    raw = npz(FIXTURE / "volume_000000.npz")
    np.savez(bad / "volume_000000.npz", hists=raw["hists"])
    with pytest.raises(nl.InputError, match=r"lacks \['pt_cloud'\].*Fix:"):
        read_dataset(bad)
    np.savez(bad / "volume_000000.npz", hists=raw["hists"], pt_cloud=raw["pt_cloud"])
    frames, meta = read_dataset(bad)  # no particles: no reference, still a sequence
    assert len(frames) == 1 and "reference_positions" not in meta
    np.savez(bad / "volume_000000.npz", **raw)
    np.savez(bad / "volume_000001.npz", **{**raw, "pt_cloud": raw["pt_cloud"] + 0.01})
    with pytest.raises(nl.InputError, match=r"volume_000001.npz: pt_cloud: differs.*Fix: pass "
                                            r"--static"):
        read_dataset(bad)
    np.savez(bad / "volume_000001.npz", **{**raw, "hists": raw["hists"][:, :64]})
    with pytest.raises(nl.InputError, match=r"volume_000001.npz: hists: has shape.*Fix:"):
        read_dataset(bad)
    with pytest.raises(nl.InputError, match="holds no volume_.*Fix:"):
        read_dataset(tmp_path, "consumer-nlos")


def test_consumer_nlos_moving_sensor_pooled_with_static(tmp_path, capsys):
    """A sensor that moves past a scene that does not (upstream cam_localization.py's capture:
    pt_cloud per frame, cam_z, no particles): --static pools every frame's zones, each at its
    own wall spot, into one confocal capture, which locate finds the hidden point from."""
    C = nl.SPEED_OF_LIGHT
    hidden = np.array([-0.4, 0.05, 0.9])  # theirs (X, Y, Z): Z away from the wall
    grid = np.stack(np.meshgrid(np.linspace(-0.15, 0.15, 4), np.linspace(-0.15, 0.15, 4)),
                    -1).reshape(16, 2)
    folder = tmp_path / "moving"
    folder.mkdir()
    for k in range(6):  # the sensor's spots slide 0.1 m a frame along X
        pt = np.column_stack([grid[:, 0] + 0.1 * k - 0.25, grid[:, 1], np.zeros(16)])
        hists = np.zeros((16, 128))
        bins = (2 * np.linalg.norm(hidden - pt, axis=1) / (C * 250e-12)).astype(int)
        hists[np.arange(16), bins] = 40.0
        hists[np.arange(16), bins + 1] = 20.0
        np.savez(folder / f"volume_{k:06d}.npz", hists=hists, pt_cloud=pt, cam_z=np.array(0.5))
    with pytest.raises(nl.InputError, match="pass --static"):
        read_dataset(folder)
    pooled = read_dataset(folder, static=True)
    # 96 zones on 36 distinct spots: a spot seen again in a later frame is summed into one
    assert pooled.n_detectors == 36 and pooled.paired
    assert np.array_equal(pooled.laser_spots, pooled.detector_spots)
    assert pooled.data.sum() == pytest.approx(96 * 60.0)  # nothing lost in the sums
    out = tmp_path / "pooled.h5"
    assert cli(["convert", str(folder), "--out", str(out), "--static"]) == 0
    assert "consumer-nlos, 36 histograms x 128 bins of 250 ps, confocal" in \
        capsys.readouterr().out
    assert cli(["locate", str(out), "--json"]) == 0
    position = np.array(json.loads(capsys.readouterr().out)["position"])
    # 250 ps bins (3.75 cm of range each) over a 0.9 m x 0.3 m aperture: a bin and a half
    assert np.linalg.norm(position - hidden) < 0.05, position  # measured 0.023 m


def track(seq_path, capsys, *extra):
    assert cli(["track", str(seq_path), "--json", "--no-progress", *extra]) == 0
    return [json.loads(line) for line in capsys.readouterr().out.splitlines()]


def test_consumer_nlos_fixture_tracks_in_front_of_the_wall(tmp_path, capsys):
    converted(tmp_path)
    capsys.readouterr()
    lines = track(tmp_path / "walk.h5", capsys)
    assert [line["frame"] for line in lines] == list(range(6))
    assert all(line["tracks"] and line["measurements"] for line in lines)
    positions = np.array([m for line in lines for m in line["measurements"]])
    assert np.all(positions[:, 2] > 0)  # the file's Z: the hidden side



@pytest.mark.skipif(not WALK.is_dir(), reason="../shared/realdata/consumer-nlos is absent")
def test_consumer_nlos_walk_first_40_frames(tmp_path, capsys):
    """The real walk's first 40 frames (2.9 s) with the defaults: every frame measured, and the
    track near the authors' particle mean (their estimate: a reference, not a truth)."""
    part = tmp_path / "first40"
    part.mkdir()
    for path in sorted(WALK.glob("volume_*.npz"))[:40]:
        shutil.copy(path, part / path.name)
    seq = converted(tmp_path, part)
    capsys.readouterr()
    lines = track(tmp_path / "walk.h5", capsys)
    assert len(lines) == 40 and all(line["measurements"] for line in lines)
    ours = np.array([line["tracks"][0]["position"] for line in lines])
    ref = np.array(seq.metadata["reference_positions"])
    gap = np.linalg.norm(ours - ref, axis=1)
    assert np.median(gap) < 0.3, np.median(gap)
