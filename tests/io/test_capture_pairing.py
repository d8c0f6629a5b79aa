"""y-tal captures with any laser/sensor pairing (nlos_cl/io/ytal/pairing.py): paired and
confocal sets round trip, files laid out by hand as y-tal writes them (confocal T_Sx_Sy,
exhaustive T_Lx_Ly_Sx_Sy and T_Li_Si, read per laser point and jointly), and the messages for
Fourier-domain, polarized and empty-origin files."""
import h5py
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.io.ytal.capture import GRID_FORMATS, H_FORMATS, to_ytal
from nlos_cl.io.ytal.reading import read_sequence
from nlos_cl.io.ytal.sequence import write_sequence

C = nl.SPEED_OF_LIGHT
AXIS = nl.TimeAxis(0.0, 16e-12, 40)
RNG = np.random.default_rng(7)


def wall(n, seed=0):
    """n distinct wall points (internal frame: y = 0)."""
    xz = np.random.default_rng(seed).permutation(100)[:n]
    return np.column_stack([0.01 * (xz % 10), np.zeros(n), 0.01 * (xz // 10)])


def counts(n):
    return RNG.integers(0, 50, size=(n, AXIS.n_bins)).astype(float)  # float32-exact


def paired_set(laser, spots):
    return nl.HistogramSet(counts(len(spots)), AXIS, spots, laser, nl.PathCalibration(C, [0.0]))


def ytal_enum(f, name, members, value):
    f.create_dataset(name, (1,), dtype=h5py.enum_dtype(members, basetype="i"))[0] = (
        members[value] if isinstance(value, str) else value)


def ytal_file(path, H, h_format, sensors, lasers, *, t_accounts=False, **extra):
    """A capture laid out as y-tal's write_hdf5 does: H time first, grids in y-tal's frame."""
    with h5py.File(path, "w") as f:
        f["H"] = H
        ytal_enum(f, "H_format", H_FORMATS, h_format)
        for name, grid in (("sensor", sensors), ("laser", lasers)):
            f[f"{name}_grid_xyz"] = to_ytal(grid).astype(np.float32)
            ytal_enum(f, f"{name}_grid_format", GRID_FORMATS, "X_Y_3" if np.ndim(grid) == 3
                      else "N_3")
        f["delta_t"] = np.float32(C * AXIS.dt_s)
        f["t_start"] = np.float32(C * 0.5 * AXIS.dt_s)
        f["t_accounts_first_and_last_bounces"] = t_accounts
        for key, value in extra.items():
            f[key] = value
    return path


def ytal_rules(path):
    """y-tal's is_laser_paired_to_sensor() and is_confocal() for T_Si / T_Sx_Sy
    (diegoroyo/tal, tal/io/capture_data.py), on the file as written."""
    with h5py.File(path, "r") as f:
        s, la = f["sensor_grid_xyz"][()], f["laser_grid_xyz"][()]
        same_format = f["sensor_grid_format"][0] == f["laser_grid_format"][0]
        return same_format and s.shape[:-1] == la.shape[:-1], np.allclose(s, la)


def assert_same(back, h):
    assert back.paired == h.paired and back.time_axis == h.time_axis
    assert np.array_equal(back.data, h.data)
    assert np.allclose(back.detector_spots, h.detector_spots, atol=1e-6)
    assert np.allclose(back.laser_spots, h.laser_spots, atol=1e-6)
    assert np.array_equal(back.calibration.offsets(back.n_detectors),
                          h.calibration.offsets(h.n_detectors))


@pytest.mark.parametrize("kind", ["paired", "confocal", "lasers_one_detector"])
def test_paired_sets_round_trip(tmp_path, kind):
    spots = wall(6)
    if kind == "confocal":
        laser = spots
    elif kind == "paired":
        laser = wall(6, seed=1)
    else:  # N lasers + one detector (CC-SOCR's layout)
        laser, spots = spots, np.tile([0.5, 0.0, 0.5], (6, 1))
    h = paired_set(laser, spots)
    path = nl.write_capture(tmp_path / "p.h5", h)
    (back,) = nl.read_capture(path)
    assert back.paired
    assert_same(back, h)
    paired, confocal = ytal_rules(path)
    assert paired and confocal == (kind == "confocal")
    (again,) = nl.read_capture(nl.write_capture(tmp_path / "q.h5", back))
    assert_same(again, back)


def test_ytal_confocal_grid_file_reads_as_one_paired_set(tmp_path):
    sx, sy = 4, 3
    grid = wall(sx * sy).reshape(sx, sy, 3)
    H = RNG.integers(0, 9, size=(AXIS.n_bins, sx, sy)).astype(np.float32)
    path = ytal_file(tmp_path / "c.h5", H, "T_Sx_Sy", grid, grid,
                     laser_xyz=np.float32([0, 0, 1]), sensor_xyz=np.float32([0, 0, 1]))
    before = path.read_bytes()
    (h,) = nl.read_capture(path)
    assert path.read_bytes() == before
    assert h.paired and h.n_detectors == sx * sy
    assert np.allclose(h.laser_spots, h.detector_spots, atol=1e-6)
    assert np.allclose(h.detector_spots, grid.reshape(-1, 3), atol=1e-6)
    assert np.array_equal(h.data, H.reshape(AXIS.n_bins, -1).T)  # row k: sensor (k // sy, k % sy)
    assert h.time_axis.dt_s == pytest.approx(AXIS.dt_s) and abs(h.time_axis.t0_s) < 1e-15


def test_paired_legs_are_removed_per_row(tmp_path):
    spots, laser = wall(5), wall(5, seed=3)
    lxyz, sxyz = np.array([0.2, 1.0, 0.1]), np.array([-0.3, 1.5, 0.0])  # internal frame
    H = np.ones((AXIS.n_bins, 5), np.float32)
    path = ytal_file(tmp_path / "legs.h5", H, "T_Si", spots, laser, t_accounts=True,
                     laser_xyz=to_ytal(lxyz).astype(np.float32),
                     sensor_xyz=to_ytal(sxyz).astype(np.float32))
    (h,) = nl.read_capture(path)
    legs = np.linalg.norm(spots - sxyz, axis=1) + np.linalg.norm(laser - lxyz, axis=1)
    np.testing.assert_allclose(h.calibration.offsets(5), -legs, atol=1e-5)


@pytest.mark.parametrize("h_format", ["T_Lx_Ly_Sx_Sy", "T_Li_Si"])
def test_exhaustive_capture_per_laser_and_joint(tmp_path, h_format):
    sensors = wall(4).reshape(2, 2, 3) if h_format == "T_Lx_Ly_Sx_Sy" else wall(4)
    lasers = wall(3, seed=5).reshape(3, 1, 3) if h_format == "T_Lx_Ly_Sx_Sy" else wall(3, 5)
    lasers = lasers + [0.0, 0.0, 2.0]  # off the sensor points
    shape = (AXIS.n_bins,) + lasers.shape[:-1] + sensors.shape[:-1]
    H = RNG.integers(0, 9, size=shape).astype(np.float32)
    path = ytal_file(tmp_path / "x.h5", H, h_format, sensors, lasers)
    per_laser = nl.read_capture(path)
    assert len(per_laser) == 3 and not any(s.paired for s in per_laser)
    flat = H.reshape(AXIS.n_bins, 3, 4)
    for i, s in enumerate(per_laser):
        assert np.allclose(s.laser_spot, lasers.reshape(-1, 3)[i], atol=1e-6)
        assert np.array_equal(s.data, flat[:, i].T)
    (joint,) = nl.read_capture(path, joint=True)
    assert joint.paired and joint.n_detectors == 12
    assert np.array_equal(joint.data, flat.reshape(AXIS.n_bins, 12).T)  # laser-major
    assert np.allclose(joint.laser_spots, np.repeat(lasers.reshape(-1, 3), 4, axis=0), atol=1e-6)
    assert np.allclose(joint.detector_spots, np.tile(sensors.reshape(-1, 3), (3, 1)), atol=1e-6)
    for i, s in enumerate(per_laser):
        assert np.array_equal(joint.select(range(4 * i, 4 * i + 4)).data, s.data)


@pytest.mark.parametrize("code", [10, 11, 12, 13])
def test_fourier_formats_are_one_clear_line(tmp_path, code):
    path = ytal_file(tmp_path / "f.h5", np.ones((AXIS.n_bins, 3), np.float32), "T_Si", wall(3),
                     np.zeros(3))
    with h5py.File(path, "a") as f:
        del f["H_format"]
        members = {**H_FORMATS, "FOURIER": code}
        ytal_enum(f, "H_format", members, code)
    with pytest.raises(nl.InputError) as info:
        nl.read_capture(path)
    text = str(info.value)
    assert "H_format" in text and "Fourier" in text and "Fix:" in text and "\n" not in text


def test_complex_h_is_named(tmp_path):
    H = np.ones((AXIS.n_bins, 3), np.complex64)
    path = ytal_file(tmp_path / "f.h5", H, "T_Si", wall(3), np.zeros(3))
    with pytest.raises(nl.InputError, match=r"H: has dtype complex64: a Fourier-domain.*Fix:"):
        nl.read_capture(path)


def test_polarized_capture_reads_its_first_stokes_channel(tmp_path):
    H = RNG.integers(0, 9, size=(AXIS.n_bins, 3, 4)).astype(np.float32)
    path = ytal_file(tmp_path / "s.h5", H, "T_Si", wall(3), np.zeros(3) + [0, 0, 2])
    with pytest.warns(UserWarning, match="Stokes"):
        (h,) = nl.read_capture(path)
    assert np.array_equal(h.data, H[..., 0].T)


def test_exhaustive_polarized_per_laser(tmp_path):
    H = RNG.integers(0, 9, size=(AXIS.n_bins, 2, 3, 4)).astype(np.float32)
    path = ytal_file(tmp_path / "s.h5", H, "T_Li_Si", wall(3), wall(2, 9) + [0, 0, 2])
    with pytest.warns(UserWarning, match="Stokes"):
        sets = nl.read_capture(path)
    assert [np.array_equal(s.data, H[:, i, :, 0].T) for i, s in enumerate(sets)] == [True] * 2


@pytest.mark.parametrize("empty", [h5py.Empty("f"), np.zeros(0, np.float32)])
def test_empty_device_origins_are_unknown(tmp_path, empty):
    path = ytal_file(tmp_path / "e.h5", np.ones((AXIS.n_bins, 3), np.float32), "T_Si", wall(3),
                     np.array([0.5, 0, 0.5]), laser_xyz=empty, sensor_xyz=empty)
    (h,) = nl.read_capture(path)
    assert h.n_detectors == 3
    with h5py.File(path, "a") as f:
        del f["t_accounts_first_and_last_bounces"]
        f["t_accounts_first_and_last_bounces"] = True
    with pytest.raises(nl.InputError, match="device positions are missing.*Fix:"):
        nl.read_capture(path)


def test_bad_pairings_name_the_field(tmp_path):
    ones = np.ones((AXIS.n_bins, 4), np.float32)
    path = ytal_file(tmp_path / "a.h5", ones, "T_Si", wall(4), wall(3, 2))
    with pytest.raises(nl.InputError, match="laser_grid_xyz: has 3 points.*Fix:"):
        nl.read_capture(path)
    spots = wall(4)
    twice = np.vstack([spots[:3], spots[:1]]), np.vstack([spots[:3] + [0, 0, 1], spots[:1] + [0, 0, 1]])
    path = ytal_file(tmp_path / "b.h5", ones, "T_Si", twice[0], twice[1])
    with pytest.raises(nl.InputError, match="pairs appear twice.*Fix:"):
        nl.read_capture(path)


def test_paired_sequence_round_trips(tmp_path):
    spots = wall(5)
    frames = [paired_set(spots, spots) for _ in range(3)]
    path = write_sequence(tmp_path / "seq.h5", frames, fps=10)
    seq = read_sequence(path)
    assert seq.layout.paired and len(seq) == 3
    for k, frame in enumerate(seq):
        assert frame.histograms.paired
        assert np.array_equal(frame.histograms.data, frames[k].data)
