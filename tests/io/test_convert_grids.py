"""`nlos-cl convert` writes a confocal scan on a regular grid (LCT, f-k, a confocal CC-SOCR
pattern) as y-tal writes its own grids (nlos_cl.io.ytal.grid_write): H_format T_Sx_Sy, H (T, Sx,
Sy), sensor and laser grids X_Y_3 with X increasing along the first axis and Y along the second
(tal.render's get_grid_xyz); anything else stays T_Si. Read back, the file gives the dataset's
histograms at the dataset's spots. Tiny synthetic datasets written here."""
import json

import h5py
import numpy as np
import pytest
import scipy.io
from test_datasets_fk import folder_v5, scene

import nlos_cl as nl
from nlos_cl.apps.cli import main as cli
from nlos_cl.io.ytal.capture import GRID_FORMATS, H_FORMATS
from nlos_cl.io.ytal.frames import to_ytal
from nlos_cl.io.ytal.grid_write import STEP_TOLERANCE, scan_grid

C = nl.SPEED_OF_LIGHT


def lct_file(tmp_path, shape=(5, 4, 60), width=0.3, cube=None):
    cube = np.random.default_rng(2).integers(0, 9, size=shape).astype(np.uint16) \
        if cube is None else cube
    path = tmp_path / "scan.mat"
    scipy.io.savemat(path, {"rect_data": cube, "width": np.array([[width]])})
    return path


def ccsocr_confocal(tmp_path, nx=4, ny=3, n_t=80, drop=0):
    """A CC-SOCR pattern whose laser and detection points coincide on an nx x ny raster of wall
    indices, listed in a shuffled order (less `drop` points: then it is no full grid)."""
    folder = tmp_path / "pattern"
    folder.mkdir()
    rng = np.random.default_rng(4)
    a, b = np.meshgrid(np.arange(nx) * 2 + 5, np.arange(ny) * 2 + 3, indexing="ij")
    idx = np.column_stack([np.zeros(a.size), a.ravel(), b.ravel()])[rng.permutation(a.size)]
    idx = idx[:len(idx) - drop]
    sig = rng.integers(0, 50, (len(idx), n_t)).astype(np.uint16)
    for name, value in (("sub_Sig", sig), ("C_i", idx.astype(np.uint8)),
                        ("C_d", idx.astype(np.uint8))):
        scipy.io.savemat(folder / f"{name}.mat", {name: value})
    return folder


def convert(src, out, *options):
    assert cli(["convert", str(src), "--out", str(out), *options]) == 0
    return nl.read_dataset(src, **({"flip": "z"} if "--flip" in options else {}),
                           **({"transpose": True} if "--transpose" in options else {}))


def same_by_spot(back, h):
    """The same histograms at the same spots, matched spot by spot (the file's row order is the
    grid's, the reader's may differ)."""
    assert back.n_detectors == h.n_detectors
    spots = np.round(h.detector_spots, 5)
    row = {tuple(s): k for k, s in enumerate(spots)}
    match = [row[tuple(s)] for s in np.round(back.detector_spots, 5)]
    assert sorted(match) == list(range(h.n_detectors))
    np.testing.assert_array_equal(back.data, h.data[match])
    np.testing.assert_allclose(back.detector_spots, h.detector_spots[match], atol=1e-6)
    np.testing.assert_allclose(back.laser_spots, h.laser_spots[match], atol=1e-6)
    assert back.time_axis == h.time_axis


def check_ytal_grid(out, shape):
    """The y-tal grid layout as tal.render writes it."""
    with h5py.File(out, "r") as f:
        assert f["H_format"][0] == H_FORMATS["T_Sx_Sy"]
        assert f["sensor_grid_format"][0] == f["laser_grid_format"][0] == GRID_FORMATS["X_Y_3"]
        assert f["H"].shape[1:] == shape
        grid, laser = f["sensor_grid_xyz"][()], f["laser_grid_xyz"][()]
        assert grid.shape == laser.shape == shape + (3,) and np.allclose(grid, laser)
        assert f["sensor_grid_normals"].shape == shape + (3,)
        dx, dy = np.diff(grid[..., 0], axis=0), np.diff(grid[..., 1], axis=1)  # X, Y increase
        assert np.all(dx > 0) and np.all(np.diff(grid[..., 0], axis=1) == 0)
        assert np.all(dy > 0) and np.all(np.diff(grid[..., 1], axis=0) == 0)
        return f["H"][()], grid


@pytest.mark.parametrize("options", [(), ("--flip", "z"), ("--transpose",)])
def test_lct_scan_is_written_as_a_ytal_grid_and_reads_back(tmp_path, capsys, options):
    out = tmp_path / "scan.h5"
    h = convert(lct_file(tmp_path), out, *options)
    assert "y-tal grid" in capsys.readouterr().out
    shape = (4, 5) if "--transpose" in options else (5, 4)
    H, grid = check_ytal_grid(out, shape)
    # H[:, i, j] is the histogram measured at grid point (i, j)
    spots = to_ytal(h.detector_spots)
    for i, j in [(0, 0), (shape[0] - 1, 1), (2, shape[1] - 1)]:
        k = int(np.argmin(np.linalg.norm(spots - grid[i, j], axis=1)))
        np.testing.assert_array_equal(H[:, i, j], h.data[k])
    (back,) = nl.read_capture(out)
    assert back.paired
    same_by_spot(back, h)


def test_fk_and_confocal_ccsocr_scans_are_grids_too(tmp_path):
    meas, tof, _ = scene()
    fk = convert(folder_v5(tmp_path, meas, tof), tmp_path / "fk.h5")
    check_ytal_grid(tmp_path / "fk.h5", (8, 8))
    same_by_spot(nl.read_capture(tmp_path / "fk.h5")[0], fk)
    cc = convert(ccsocr_confocal(tmp_path), tmp_path / "cc.h5")  # rows listed shuffled
    check_ytal_grid(tmp_path / "cc.h5", (4, 3))
    same_by_spot(nl.read_capture(tmp_path / "cc.h5")[0], cc)


def test_what_is_not_a_confocal_grid_stays_a_list(tmp_path, capsys):
    folder = ccsocr_confocal(tmp_path, drop=1)  # one raster point missing
    h = convert(folder, tmp_path / "cc.h5")
    assert "H_format T_Si" in capsys.readouterr().out
    with h5py.File(tmp_path / "cc.h5", "r") as f:
        assert f["H_format"][0] == H_FORMATS["T_Si"] and f["H"].shape == (80, 11)
        assert f["sensor_grid_format"][0] == GRID_FORMATS["N_3"]
    same_by_spot(nl.read_capture(tmp_path / "cc.h5")[0], h)


def grid_set(nx=5, ny=4, step=0.05, laser=None):
    x, z = np.meshgrid(np.arange(nx) * step, np.arange(ny) * step, indexing="ij")
    spots = np.column_stack([x.ravel(), np.zeros(x.size), z.ravel()])
    axis = nl.TimeAxis(0.0, 1e-11, 8)
    return nl.HistogramSet(np.ones((nx * ny, 8)), axis, spots,
                           spots if laser is None else laser(spots),
                           nl.PathCalibration(C, [0.0]))


def moved(h, rows, by):
    spots = h.detector_spots.copy()
    spots[rows] += by
    return nl.HistogramSet(h.data, h.time_axis, spots, spots, h.calibration)


def test_the_grid_is_decided_from_the_spots_with_a_tolerance():
    h = grid_set()
    assert scan_grid(h).shape == (5, 4)
    step = 0.05
    # float32 rounding and a point within the tolerance: still the grid
    assert scan_grid(moved(h, [3], [0.3 * STEP_TOLERANCE * step, 0, 0])).shape == (5, 4)
    assert scan_grid(moved(h, slice(None), [0, 0, 0]).select(np.arange(20)[::-1])).shape == (5, 4)
    not_grids = {
        "a point off its grid line": moved(h, [3], [3 * STEP_TOLERANCE * step, 0, 0]),
        "a point off the wall plane": moved(h, [3], [0, 3 * STEP_TOLERANCE * step, 0]),
        "a missing point": h.select(np.arange(19)),
        "a point twice": h.select(np.r_[np.arange(19), 0]),
        "not confocal": grid_set(laser=lambda s: s + [0.01, 0, 0]),
        "one laser": nl.HistogramSet(h.data, h.time_axis, h.detector_spots, np.zeros(3),
                                     h.calibration),
        "a line": grid_set(nx=20, ny=1),
        "uneven steps": moved(h, slice(0, 4), [-0.02, 0, 0]),  # first column 0.07 from the next
    }
    c, s = np.cos(0.3), np.sin(0.3)
    rotated = h.detector_spots @ np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]]).T
    not_grids["a rotated grid"] = nl.HistogramSet(h.data, h.time_axis, rotated, rotated,
                                                  h.calibration)
    assert {k: scan_grid(v) for k, v in not_grids.items()} == dict.fromkeys(not_grids)


@pytest.mark.parametrize("target", [False, True])
def test_a_converted_scan_without_a_target_is_not_detected(tmp_path, capsys, target):
    """Issue 59 item 3: a converted scan of noise only locates to exit 3, "detected": false;
    the same scan with a point in it is detected (so the no is not the scan's doing)."""
    n, n_t, width, dt = 8, 1024, 0.2, 4e-12
    cube = np.random.default_rng(5).poisson(0.05, (n, n, n_t)).astype(np.uint16)
    if target:  # LCT's rule: rect_data[i, j] at (x, z) = (u_i, u_j), photons at 2 r / c
        u = np.linspace(-width, width, n)
        x, z = np.meshgrid(u, u, indexing="ij")
        r = np.linalg.norm(np.stack([x, 0 * x, z], -1) - [0.05, 0.45, -0.03], axis=-1)
        cube[np.arange(n)[:, None], np.arange(n)[None, :], (2 * r / (C * dt)).astype(int)] += 40
    out = tmp_path / "scan.h5"
    convert(lct_file(tmp_path, cube=cube, width=width), out)
    check_ytal_grid(out, (n, n))
    capsys.readouterr()
    code = cli(["locate", str(out), "--json"])
    answer = json.loads(capsys.readouterr().out)
    assert (code, answer["detected"]) == ((0, True) if target else (3, False))
