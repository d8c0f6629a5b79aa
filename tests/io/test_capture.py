"""y-tal HDF5 captures: round trip, a file laid out by hand as y-tal writes it, bad files."""
import hashlib

import h5py
import numpy as np
import pytest
import yaml

import nlos_cl as nl
from nlos_cl.io.ytal.capture import GRID_FORMATS, H_FORMATS, from_ytal, to_ytal

C = nl.SPEED_OF_LIGHT
GRID = nl.Grid.from_ranges(x=(2.5, 5.5), y=(0.5, 3.5), step_m=0.01)


@pytest.fixture(scope="module")
def paper_hist(runtime):
    axis = nl.TimeAxis(2 * 20 / C + 25e-9, 10e-12, 1500)
    return nl.simulate(nl.paper_scene(), axis, backend=runtime).histograms()


def test_frames_map_by_a_rotation():
    ours = np.array([[1.0, 2.0, 3.0], [-0.5, 0.0, 0.2]])
    assert np.allclose(from_ytal(to_ytal(ours)), ours)
    assert np.allclose(to_ytal([0, 1, 0]), [0, 0, 1])  # our wall normal is y-tal's +Z
    assert np.allclose(to_ytal([0, 0, 1]), [0, 1, 0])  # our up is y-tal's Y
    m = to_ytal(np.eye(3))
    assert np.isclose(np.linalg.det(m), 1.0)


def test_round_trip_is_lossless(paper_hist, tmp_path):
    path = nl.write_capture(tmp_path / "a.h5", paper_hist, metadata={"run": 7})
    (back,) = nl.read_capture(path)
    assert back.time_axis == paper_hist.time_axis
    assert back.calibration.a_m_per_s == paper_hist.calibration.a_m_per_s
    assert np.array_equal(back.calibration.b_m, paper_hist.calibration.b_m)
    assert np.allclose(back.detector_spots, paper_hist.detector_spots, atol=1e-7)
    assert np.allclose(back.laser_spot, paper_hist.laser_spot)
    assert np.array_equal(back.truth, paper_hist.truth)
    # y-tal stores H as float32: the first trip rounds to float32, later trips are exact
    np.testing.assert_allclose(back.data, paper_hist.data, rtol=1e-7, atol=1e-7 * np.abs(
        paper_hist.data).max())
    path2 = nl.write_capture(tmp_path / "b.h5", back)
    (again,) = nl.read_capture(path2)
    assert np.array_equal(again.data, back.data)
    loc = nl.locate(nl.gauss_filter(back), GRID, estimator="paper")
    assert loc.error_m < 0.05


def test_written_file_has_ytal_fields_and_types(paper_hist, tmp_path):
    path = nl.write_capture(tmp_path / "a.h5", paper_hist)
    with h5py.File(path, "r") as f:
        assert f["H"].dtype == np.float32 and f["H"].shape == (1500, 3)  # time axis first
        assert h5py.check_enum_dtype(f["H_format"].dtype) == H_FORMATS
        assert f["H_format"][0] == H_FORMATS["T_Si"]
        assert f["sensor_grid_format"][0] == GRID_FORMATS["N_3"]
        assert f["delta_t"][()] == pytest.approx(C * 10e-12, rel=1e-6)  # metres of path
        assert not f["t_accounts_first_and_last_bounces"][()]
        info = yaml.safe_load(f["scene_info"][()])
        assert info["nlos_cl"]["time_axis"]["n_bins"] == 1500
        assert set(f.keys()) <= {"H", "H_format", "sensor_xyz", "sensor_grid_xyz",
                                 "sensor_grid_normals", "sensor_grid_format", "laser_xyz",
                                 "laser_grid_xyz", "laser_grid_normals", "laser_grid_format",
                                 "volume_format", "delta_t", "t_start",
                                 "t_accounts_first_and_last_bounces", "scene_info"}


def ytal_enum(f, name, members, value):
    ds = f.create_dataset(name, (1,), dtype=h5py.enum_dtype(members, basetype="i"))
    ds[0] = members[value]


def test_hand_written_ytal_capture_locates(runtime, tmp_path):
    """Written field by field as y-tal's write_hdf5 does: T_Sx_Sy with X_Y_3 grids, enums as
    int32 enum datasets, None as h5py.Empty, scene_info as YAML, and both bounces included."""
    # Four sensor spots 0.5 m around (-1, 0, 0) on the wall, so the sensor device 20 m in front
    # of (-1, 0, 0) is equally far from all: one t_start fits every sensor.
    centre = np.array([-1.0, 0.0, 0.0])
    spots = centre + np.array([[-0.5, 0, 0], [0.5, 0, 0], [0, 0, -0.5], [0, 0, 0.5]])
    setup = nl.paper_setup(detector_spots=spots)
    scene = nl.Scene(setup, nl.Target(nl.rectangle()), 0.01, truth=(4.0, 2.0, 0.0))
    sim = nl.simulate(scene, nl.TimeAxis(2 * 20 / C + 25e-9, 10e-12, 1500), backend=runtime)
    hist = sim.histograms()
    d1 = 20.0
    d4 = float(np.hypot(20.0, 0.5))
    # hidden path at bin centre k = c (t0 + (k + 0.5) dt) + b; y-tal: t_start + k dt - d1 - d4
    b = hist.calibration.b_m[0]
    t_start = C * (hist.time_axis.t0_s + 0.5 * hist.time_axis.dt_s) + b + d1 + d4
    path = tmp_path / "ytal.hdf5"
    with h5py.File(path, "w") as f:
        f["H"] = hist.data.T.reshape(1500, 2, 2).astype(np.float32)
        ytal_enum(f, "H_format", H_FORMATS, "T_Sx_Sy")
        f["sensor_xyz"] = to_ytal(centre + [0, 20.0, 0]).astype(np.float32)
        f["sensor_grid_xyz"] = to_ytal(spots).reshape(2, 2, 3).astype(np.float32)
        f["sensor_grid_normals"] = np.tile([0, 0, 1.0], (2, 2, 1)).astype(np.float32)
        ytal_enum(f, "sensor_grid_format", GRID_FORMATS, "X_Y_3")
        f["laser_xyz"] = to_ytal([0, 20.0, 0]).astype(np.float32)
        f["laser_grid_xyz"] = to_ytal([0, 0, 0]).astype(np.float32)
        f["laser_grid_normals"] = np.array([0, 0, 1.0], np.float32)
        ytal_enum(f, "laser_grid_format", GRID_FORMATS, "N_3")
        f["volume_format"] = h5py.Empty(float)
        f["delta_t"] = np.float32(C * 10e-12)
        f["t_start"] = np.float32(t_start)
        f["t_accounts_first_and_last_bounces"] = True
        f["scene_info"] = yaml.dump({"original_format": "HDF5_TAL", "config": {"name": "x"}})
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    (capture,) = nl.read_capture(path)
    assert hashlib.sha256(path.read_bytes()).hexdigest() == digest  # never modified by reading
    assert np.allclose(capture.detector_spots, spots, atol=1e-6)
    # the file's mapping equals the simulation's to float32 precision (~4e-6 m of path)
    np.testing.assert_allclose(capture.hidden_path_axis(), hist.hidden_path_axis(), atol=2e-5)
    loc = nl.locate(nl.gauss_filter(capture), GRID, estimator="paper")
    assert np.linalg.norm(loc.position - [4.0, 2.0, 0.0]) < 0.05


def test_several_laser_points_give_one_set_each(paper_hist, tmp_path):
    path = tmp_path / "two_lasers.h5"
    lasers = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    with h5py.File(path, "w") as f:
        # (T, L, S), as y-tal 0.20's reconstruct reads value 4 (T_Li_Si)
        f["H"] = np.stack([paper_hist.data.T, 0.5 * paper_hist.data.T], axis=1).astype(np.float32)
        ytal_enum(f, "H_format", H_FORMATS, "T_Li_Si")
        f["sensor_grid_xyz"] = to_ytal(paper_hist.detector_spots).astype(np.float32)
        ytal_enum(f, "sensor_grid_format", GRID_FORMATS, "N_3")
        f["laser_grid_xyz"] = to_ytal(lasers).astype(np.float32)
        ytal_enum(f, "laser_grid_format", GRID_FORMATS, "N_3")
        axis = paper_hist.time_axis
        f["delta_t"] = np.float32(C * axis.dt_s)
        f["t_start"] = np.float32(C * (axis.t0_s + 0.5 * axis.dt_s) + paper_hist.calibration.b_m[0])
        f["t_accounts_first_and_last_bounces"] = False
    sets = nl.read_capture(path)
    assert len(sets) == 2
    for s in sets:
        assert nl.locate(nl.gauss_filter(s), GRID, estimator="paper").error_m is None  # no truth in a plain file
        assert np.linalg.norm(nl.locate(nl.gauss_filter(s), GRID, estimator="paper").position - [4, 2, 0]) < 0.05


def broken(tmp_path, paper_hist, edit):
    path = nl.write_capture(tmp_path / "x.h5", paper_hist)
    with h5py.File(path, "a") as f:
        edit(f)
    return path


@pytest.mark.parametrize("field, edit", [
    ("missing field(s) ['delta_t']", lambda f: f.__delitem__("delta_t")),
    ("H: has dtype", lambda f: (f.__delitem__("H"), f.__setitem__("H", np.array([b"x"] * 3)))),
    ("H: has shape", lambda f: (f.__delitem__("H"), f.__setitem__("H", np.zeros((10, 4), np.float32)))),
    ("delta_t: is 1e-11: that looks like seconds",
     lambda f: (f.__delitem__("delta_t"), f.__setitem__("delta_t", np.float32(1e-11)))),
    ("H: 1 values are NaN", lambda f: f["H"].__setitem__((5, 1), np.nan)),
    ("sensor_grid_xyz: contains NaN", lambda f: f["sensor_grid_xyz"].__setitem__((0, 0), np.inf)),
    ("H_format: value", lambda f: f["H_format"].__setitem__(0, 0)),
    ("sensor_grid_xyz: has shape", lambda f: (f.__delitem__("sensor_grid_xyz"),
                                              f.__setitem__("sensor_grid_xyz", np.zeros((3, 2))))),
])
def test_bad_files_name_the_field(paper_hist, tmp_path, field, edit):
    path = broken(tmp_path, paper_hist, edit)
    before = path.read_bytes()
    with pytest.raises(nl.InputError) as info:
        nl.read_capture(path)
    assert field in str(info.value) and "Fix:" in str(info.value)
    assert path.read_bytes() == before


@pytest.mark.parametrize("keep", [0, 5, 100, 2000, 0.5, 0.9, -1])
def test_truncated_file_is_a_clear_error(paper_hist, tmp_path, keep):
    """Cut anywhere (even one byte short, where every field is still listed): "incomplete or
    corrupted file", never "missing field(s)"; the file stays as it was."""
    path = nl.write_capture(tmp_path / "x.h5", paper_hist)
    full = path.read_bytes()
    cut = full[:keep if isinstance(keep, int) and keep >= 0 else
               len(full) - 1 if keep == -1 else int(keep * len(full))]
    path.write_bytes(cut)
    with pytest.raises(nl.InputError, match="incomplete or corrupted file") as info:
        nl.read_capture(path)
    assert "missing field" not in str(info.value) and "Fix:" in str(info.value)
    assert path.read_bytes() == cut


def test_confocal_capture_reads_as_one_paired_set(paper_hist, tmp_path):
    """(Refused before issue 21.) A laser grid equal to the sensor grid is y-tal's confocal
    capture: one set, each histogram's laser spot its own detector spot."""
    def confocal(f):
        del f["laser_grid_xyz"]
        f["laser_grid_xyz"] = f["sensor_grid_xyz"][()]
    [h] = nl.read_capture(broken(tmp_path, paper_hist, confocal))
    assert h.paired and np.allclose(h.laser_spots, h.detector_spots)


def test_cli_simulate_then_locate(tmp_path):
    import json
    import subprocess
    import sys
    out = tmp_path / "c.h5"
    run = lambda *a: subprocess.run([sys.executable, "-m", "nlos_cl.apps.cli", *a],  # noqa: E731
                                    capture_output=True, text=True, timeout=600)
    made = run("simulate", "--out", str(out), "--facet", "0.02", "--snr-db", "10")
    assert made.returncode == 0, made.stderr
    found = run("locate", str(out), "--json", "--map", str(tmp_path / "m.npz"))
    assert found.returncode == 0, found.stderr
    result = json.loads(found.stdout)
    # reported in the file's own (y-tal) frame: nlos_cl's (4, 2, 0) is y-tal's (-4, 0, 2)
    assert result["frame"]["name"] == "ytal" and result["truth"] == [-4.0, 0.0, 2.0]
    assert result["error_m"] < 0.05
    assert np.linalg.norm(np.subtract(result["position"], result["truth"])) < 0.05
    region = result["region"]  # derived from the capture: the plane of the collinear spots
    assert region["ranges_m"][1] == [0.0, 0.0] and region["ranges_m"][0][0] < -4 < 4 < \
        region["ranges_m"][0][1]
    assert np.load(tmp_path / "m.npz")["score"].size == region["cells"]
