"""The f-k migration format (nlos_cl.io.datasets.fk): tiny synthetic scenes written here as the
upstream files are laid out (meas (N, N, T) counts with MATLAB's (y, x, t) axes, tofgrid (N, N)
in ps), in MATLAB v5 (scipy.io) and v7.3 (HDF5); no real data is committed."""
import json

import numpy as np
import pytest
import scipy.io

import nlos_cl as nl
from nlos_cl.apps.cli import main as cli
from nlos_cl.io.datasets import fk
from test_input_checks import _mat73

C = nl.SPEED_OF_LIGHT
HIDDEN = np.array([0.3, 0.9, 0.4])  # internal frame: 0.9 m in front of the wall
N, T, DT_PS = 8, 1000, 32.0


def scene(n=N):
    """(meas, tofgrid, path): one hidden point; scan point (i, j) at (x, z) = (u_j, u_(n-1-i)),
    u = linspace(-1, 1, n) (rows from the top); its photon at record bin shift + the bin of
    the round trip 2 |p - spot| (the bins after the shift: t = 0 at the wall bounce)."""
    rng = np.random.default_rng(3)
    u = np.linspace(-1.0, 1.0, n)
    x, z = u[None, :].repeat(n, 0), u[::-1, None].repeat(n, 1)
    path = 2 * np.linalg.norm(np.stack([x, np.zeros_like(x), z], -1) - HIDDEN, axis=-1)
    tof = rng.uniform(3000.0, 6000.0, (n, n))  # ps to each scan point
    meas = rng.poisson(0.02, (n, n, T)).astype(np.float64)  # dark counts
    k = np.floor(tof / DT_PS).astype(int) + np.floor(path / (C * DT_PS * 1e-12)).astype(int)
    meas[np.arange(n)[:, None], np.arange(n)[None, :], k] += 50
    return meas, tof, path


def folder_v5(tmp_path, meas, tof, name="meas_10min.mat"):
    folder = tmp_path / "statue"
    folder.mkdir(exist_ok=True)
    scipy.io.savemat(folder / name, {"meas": meas})
    scipy.io.savemat(folder / "tof.mat", {"tofgrid": tof})
    return folder


def test_fk_scene_is_rectified_confocal_and_files_untouched(tmp_path):
    meas, tof, path = scene()
    folder = folder_v5(tmp_path, meas, tof)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    h = nl.read_dataset(folder)  # detected: a folder with meas*.mat and tof*.mat
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    assert h.paired and np.allclose(h.laser_spots, h.detector_spots)
    assert h.n_detectors == N * N and h.time_axis.n_bins == fk.CROP_BINS
    assert h.time_axis.dt_s == pytest.approx(32e-12) and h.time_axis.t0_s == 0
    assert np.all(h.detector_spots[:, 1] == 0)
    # row 0 is the top of the scan, columns run along x
    assert np.allclose(h.detector_spots[0], [-1, 0, 1]) and np.allclose(h.detector_spots[N - 1],
                                                                       [1, 0, 1])
    # each histogram's peak holds the round trip to the hidden point, to half a bin
    peak = h.hidden_path_axis()[np.arange(N * N), h.data.argmax(axis=1)]
    assert np.all(np.abs(peak - path.ravel()) <= 0.5 * C * 32e-12 + 1e-12)
    # counts stay whole numbers (the Poisson likelihood applies)
    assert np.array_equal(h.data, np.round(h.data))


def test_fk_v73_reads_as_v5_and_blocks_sum_neighbours(tmp_path):
    meas, tof, _ = scene()
    v5 = nl.read_dataset(folder_v5(tmp_path, meas, tof))
    other = tmp_path / "v73"
    other.mkdir()
    _mat73(other / "meas_10min.mat", {"meas": meas})
    _mat73(other / "tof.mat", {"tofgrid": tof})
    v73 = nl.read_dataset(other / "meas_10min.mat")  # a file: its tof.mat found beside it
    np.testing.assert_array_equal(v73.data, v5.data)
    np.testing.assert_array_equal(v73.detector_spots, v5.detector_spots)
    blocks = nl.read_dataset(other, "fk", block=2)
    assert blocks.n_detectors == (N // 2) ** 2
    cube = v5.data.reshape(N, N, -1)
    summed = cube.reshape(N // 2, 2, N // 2, 2, -1).sum(axis=(1, 3)).reshape((N // 2) ** 2, -1)
    np.testing.assert_array_equal(blocks.data, summed)
    spots = v5.detector_spots.reshape(N // 2, 2, N // 2, 2, 3).mean(axis=(1, 3)).reshape(-1, 3)
    np.testing.assert_allclose(blocks.detector_spots, spots, atol=1e-12)


def test_fk_default_block_bounds_the_histograms():
    assert [fk._default_block(n) for n in (8, 32, 64, 128, 512)] == [1, 1, 1, 2, 8]
    assert fk._default_block(100) == 2  # 50 a side
    assert fk._default_block(130) == 2  # 65 a side: no larger power of two divides 130


def test_fk_orientation_options(tmp_path):
    meas, tof, _ = scene()
    folder = folder_v5(tmp_path, meas, tof)
    h = nl.read_dataset(folder)
    flipped = nl.read_dataset(folder, "fk", flip="x")
    np.testing.assert_allclose(flipped.detector_spots[:, 0], -h.detector_spots[:, 0])
    np.testing.assert_array_equal(flipped.data, h.data)
    swapped = nl.read_dataset(folder, "fk", transpose=True)
    np.testing.assert_array_equal(swapped.data.reshape(N, N, -1),
                                  h.data.reshape(N, N, -1).transpose(1, 0, 2))
    np.testing.assert_array_equal(swapped.detector_spots, h.detector_spots)


@pytest.mark.parametrize("case, message", [
    ("two", "holds 2 meas\\*.mat files .*pass one of them"),
    ("no_tof", "has no tof_10min.mat or tof.mat beside it"),
    ("tof_shape", "tofgrid: is \\(4, 4\\), the scan 8 x 8"),
    ("four_d", "is 4-D .*--format fk-interactive"),
    ("tof_late", "holds times outside the record"),
    ("crop", "crop_bins: must be a bin count in 2..1000"),
    ("crop_zero", "crop_bins: must be a bin count in 2..1000, got 0"),
])
def test_fk_refusals(tmp_path, case, message):
    meas, tof, _ = scene()
    folder = folder_v5(tmp_path, meas, tof)
    options = {}
    if case == "two":
        scipy.io.savemat(folder / "meas_30min.mat", {"meas": meas})
    elif case == "no_tof":
        (folder / "tof.mat").unlink()
    elif case == "tof_shape":
        scipy.io.savemat(folder / "tof.mat", {"tofgrid": tof[:4, :4]})
    elif case == "four_d":
        scipy.io.savemat(folder / "meas_10min.mat", {"meas": meas[None, :, :, :50]})
    elif case == "tof_late":
        scipy.io.savemat(folder / "tof.mat", {"tofgrid": tof + T * DT_PS})
    elif case == "crop":
        options = {"crop_bins": T + 1}
    elif case == "crop_zero":
        options = {"crop_bins": 0}
    src = folder if case != "no_tof" else folder / "meas_10min.mat"
    with pytest.raises(nl.InputError, match=message):
        nl.read_dataset(src, "fk", **options)


def test_fk_convert_then_locate_finds_the_point(tmp_path, capsys):
    meas, tof, _ = scene()
    folder = folder_v5(tmp_path, meas, tof)
    out = tmp_path / "statue.h5"
    assert cli(["convert", str(folder), "--out", str(out)]) == 0
    assert "fk, 64 histograms x 512 bins of 32 ps, confocal" in capsys.readouterr().out
    assert cli(["locate", str(out), "--json"]) == 0
    answer = json.loads(capsys.readouterr().out)
    # y-tal frame: the wall at Z = 0, depth along Z; the hidden point is 0.9 m deep
    position = np.asarray(answer["position"])
    assert abs(position[2] - HIDDEN[1]) <= 0.03, answer


def walking(frames=3, n=N):
    """A 4-D meas (F, n, n, T): the hidden point moving 0.1 m in x a frame."""
    cubes, paths = [], []
    global HIDDEN
    keep = HIDDEN.copy()
    try:
        for f in range(frames):
            HIDDEN = keep + [0.1 * f, 0.0, 0.0]
            meas, tof, path = scene(n)
            cubes.append(meas)
            paths.append(path)
    finally:
        HIDDEN = keep
    return np.stack(cubes), tof, paths


def test_fk_interactive_is_a_sequence_of_rectified_frames(tmp_path, capsys):
    meas, tof, paths = walking()
    folder = tmp_path / "interactive"
    folder.mkdir()
    scipy.io.savemat(folder / "meas_8.mat", {"meas": meas})
    scipy.io.savemat(folder / "tof_8.mat", {"tofgrid": tof})
    with pytest.raises(nl.InputError, match="fps: is not known for a 8 x 8 interactive scan"):
        nl.read_dataset(folder)  # detected from the 4-D meas; the README's rates are 32 / 64
    frames, meta = nl.read_dataset(folder, fps=4.0)
    assert [t for t, _ in frames] == [0.0, 0.25, 0.5] and meta["fps"] == 4.0
    for (_, h), path in zip(frames, paths):
        assert h.time_axis.n_bins == T  # the 1,024 bins kept by default: the record's 1,000
        peak = h.hidden_path_axis()[np.arange(N * N), h.data.argmax(axis=1)]
        assert np.all(np.abs(peak - path.ravel()) <= 0.5 * C * 32e-12 + 1e-12)
    v73 = tmp_path / "v73"
    v73.mkdir()
    _mat73(v73 / "meas_8.mat", {"meas": meas})
    _mat73(v73 / "tof_8.mat", {"tofgrid": tof})
    again, _ = nl.read_dataset(v73 / "meas_8.mat", fps=4.0)
    for (_, a), (_, b) in zip(frames, again):
        np.testing.assert_array_equal(a.data, b.data)
    out = tmp_path / "interactive.h5"
    assert cli(["convert", str(folder), "--out", str(out), "--fps", "4"]) == 0
    assert "fk-interactive, 3 frames at 4 Hz" in capsys.readouterr().out
    assert cli(["track", str(out), "--json", "--no-progress"]) == 0
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    # y-tal frame (X, Y, Z) = (-x, z, depth): the point at x = 0.5 m in the last frame
    truth = [-(HIDDEN[0] + 0.2), HIDDEN[2], HIDDEN[1]]
    assert np.linalg.norm(np.asarray(last["measurements"][0]) - truth) <= 0.03, last
    with pytest.raises(nl.InputError, match="--format fk-interactive"):
        nl.read_dataset(folder, "fk")


def test_an_fk_file_read_as_lct_says_which_format(tmp_path):
    meas, tof, _ = scene()
    folder = folder_v5(tmp_path, meas, tof)
    with pytest.raises(nl.InputError, match="rect_data: is missing; the file holds `meas`.*"
                                            "--format fk"):
        nl.read_dataset(folder / "meas_10min.mat", "lct")


def test_fk_nonplanar_scan_is_planarized_as_upstream_does(tmp_path, capsys):
    """upstream's `nonplanar` scene: calibration.mat holds z_offset (each scan point's offset
    towards the hidden side) and width (the scan's full side). The reader applies upstream's
    naive correction (each histogram 2 floor(z_offset / (c bin)) bins later) and takes the
    side from width; locate then finds the point (the correction is exact along the normal,
    2 z (1 - cos theta) of path off elsewhere: up to 4.4 cm here)."""
    n, width = 16, 1.0
    u = np.linspace(-width / 2, width / 2, n)
    x, z = u[None, :].repeat(n, 0), u[::-1, None].repeat(n, 1)
    z_off = 0.1 * (1.0 - (x ** 2 + z ** 2) / 0.5)  # a bowl up to 0.1 m towards the scene
    spots = np.stack([x, z_off, z], -1)
    path = 2 * np.linalg.norm(spots - HIDDEN, axis=-1)
    tof = np.random.default_rng(4).uniform(3000.0, 6000.0, (n, n))
    meas = np.zeros((n, n, T))
    k = np.floor(tof / DT_PS).astype(int) + np.floor(path / (C * DT_PS * 1e-12)).astype(int)
    meas[np.arange(n)[:, None], np.arange(n)[None, :], k] = 50.0
    folder = folder_v5(tmp_path, meas, tof)
    scipy.io.savemat(folder / "calibration.mat", {"z_offset": z_off, "width": [[width]]})
    h = nl.read_dataset(folder)
    assert np.allclose(h.detector_spots[[0, n - 1], 0], [-0.5, 0.5])  # the side from width
    planar = 2 * np.linalg.norm(np.stack([x, 0 * x, z], -1) - HIDDEN, axis=-1).ravel()
    peak = h.hidden_path_axis()[np.arange(n * n), h.data.argmax(axis=1)]
    # as if on the plane, to the naive correction's own error 2 z (1 - cos theta) plus the
    # bins it and the record round to (3 bins of path)
    cos = (HIDDEN[1] - z_off) / np.linalg.norm(spots - HIDDEN, axis=-1)
    bound = 2 * z_off * (1 - cos) + 3 * C * DT_PS * 1e-12
    assert np.all(np.abs(peak - planar) <= bound.ravel() + 1e-9)
    out = tmp_path / "nonplanar.h5"
    assert cli(["convert", str(folder), "--out", str(out)]) == 0
    assert cli(["locate", str(out), "--json"]) == 0
    position = np.asarray(json.loads(capsys.readouterr().out.splitlines()[-1])["position"])
    assert np.linalg.norm(position - [-HIDDEN[0], HIDDEN[2], HIDDEN[1]]) <= 0.03, position
