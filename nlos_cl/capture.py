"""Captures in y-tal's HDF5 layout (`tal.io.NLOSCaptureData`), read and written with h5py.

y-tal itself is not a dependency (it pins numpy < 2); the layout is followed field by field:

| y-tal field | dtype, shape | ours |
|---|---|---|
| H | float32, time axis first: (T, S) for H_format T_Si, (T, Sx, Sy) for T_Sx_Sy; (T, Lx, Ly, Sx, Sy) for T_Lx_Ly_Sx_Sy and (T, S, L) for T_Si_Li (several laser points) | HistogramSet.data (detectors x bins), one set per laser point |
| H_format | enum dataset (int32, shape (1,)): UNKNOWN 0, T_Sx_Sy 1, T_Lx_Ly_Sx_Sy 2, T_Si 3, T_Si_Li 4 | |
| sensor_grid_xyz, sensor_grid_normals | float32 (S, 3) [N_3] or (Sx, Sy, 3) [X_Y_3] | detector_spots, flattened row-major |
| laser_grid_xyz, laser_grid_normals | float32 (L, 3) / (3,) [N_3] or (Lx, Ly, 3) [X_Y_3] | laser_spot |
| sensor_grid_format, laser_grid_format | enum: UNKNOWN 0, N_3 1, X_Y_3 2 | |
| sensor_xyz, laser_xyz | float32 (3,): the devices themselves | written d metres in front of the wall |
| delta_t, t_start | float32, metres of optical path | time_axis (seconds = metres / c); y-tal's sample k is our bin centre |
| t_accounts_first_and_last_bounces | bool | if true, |laser_xyz - laser point| + |sensor point - sensor_xyz| is removed from the path |
| scene_info | YAML string | kept; ours under the key `nlos_cl` (y-tal rejects unknown top-level fields, so extra metadata rides here) |

Frames: y-tal's relay wall is Z = 0 with the hidden space at Z > 0; ours is y = 0 with y > 0
hidden and z up. Points map by the proper rotation (X, Y, Z) = (-x, z, y), i.e. y-tal's Y is our
up and its Z our depth; back by (x, y, z) = (-X, Z, Y).

Several laser points (T_Lx_Ly_Sx_Sy, T_Si_Li) give one HistogramSet per laser point, each
located separately. Confocal captures (every sensor point paired with its own laser point)
are not supported: the ellipse model needs one laser spot per histogram set.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .errors import InputError, require
from .histograms import HistogramSet, PathCalibration, TimeAxis
from .scene import SPEED_OF_LIGHT

H_FORMATS = {"UNKNOWN": 0, "T_Sx_Sy": 1, "T_Lx_Ly_Sx_Sy": 2, "T_Si": 3, "T_Si_Li": 4}
GRID_FORMATS = {"UNKNOWN": 0, "N_3": 1, "X_Y_3": 2}
REQUIRED = ("H", "H_format", "sensor_grid_xyz", "laser_grid_xyz", "delta_t", "t_start",
            "t_accounts_first_and_last_bounces")

# ours (x, y, z) -> y-tal (X, Y, Z) = (-x, z, y): a rotation (determinant +1)
_TO_YTAL = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])


def to_ytal(points) -> np.ndarray:
    return np.asarray(points, dtype=np.float64) @ _TO_YTAL.T


def from_ytal(points) -> np.ndarray:
    return np.asarray(points, dtype=np.float64) @ _TO_YTAL  # the inverse of a rotation


# ---------------------------------------------------------------------------- writing

def write_capture(path, histograms: HistogramSet, *, device_distance_m: float = 20.0,
                  metadata: dict | None = None, compression: int = 4) -> Path:
    """Write one HistogramSet as a y-tal capture (H_format T_Si, sensor grid N_3).

    y-tal has one time origin for all sensors, so every detector must share the calibration
    offset; the slope a becomes the optical-path-per-second of delta_t. Our exact time axis,
    calibration, truth and `metadata` ride in scene_info['nlos_cl'] for a lossless round trip.
    """
    import h5py
    import yaml

    h = histograms
    offsets = h.calibration.offsets(h.n_detectors)
    require(bool(np.allclose(offsets, offsets[0], rtol=0, atol=1e-9)), "calibration.b_m",
            "differs between detectors, but a y-tal capture has a single t_start",
            "write one file per group of detectors that share an offset")
    a, axis = h.calibration.a_m_per_s, h.time_axis
    delta_t = a * axis.dt_s
    t_start = a * (axis.t0_s + 0.5 * axis.dt_s) + offsets[0]  # sample k = our bin centre k
    spots = to_ytal(h.detector_spots)
    laser = to_ytal(h.laser_spot)
    wall_normal = to_ytal([0.0, 1.0, 0.0])
    ours = {"format_version": 1,
            "time_axis": {"t0_s": axis.t0_s, "dt_s": axis.dt_s, "n_bins": axis.n_bins},
            "calibration": {"a_m_per_s": a, "b_m": [float(b) for b in h.calibration.b_m]},
            "truth": None if h.truth is None else [float(v) for v in h.truth],
            "allow_negative": bool(h.allow_negative), "units": "W",
            "frame": "nlos_cl (x, y, z) = (-X, Z, Y) of this file"}
    if metadata:
        ours["metadata"] = metadata
    path = Path(path)
    with h5py.File(path, "w") as f:
        f.create_dataset("H", data=np.ascontiguousarray(h.data.T, dtype=np.float32),
                         compression="gzip" if compression else None,
                         compression_opts=compression or None)
        _enum(f, "H_format", H_FORMATS, "T_Si")
        f["sensor_xyz"] = (spots.mean(axis=0) + device_distance_m * wall_normal).astype(np.float32)
        f["sensor_grid_xyz"] = spots.astype(np.float32)
        f["sensor_grid_normals"] = np.tile(wall_normal, (h.n_detectors, 1)).astype(np.float32)
        _enum(f, "sensor_grid_format", GRID_FORMATS, "N_3")
        f["laser_xyz"] = (laser + device_distance_m * wall_normal).astype(np.float32)
        f["laser_grid_xyz"] = laser.reshape(1, 3).astype(np.float32)
        f["laser_grid_normals"] = wall_normal.reshape(1, 3).astype(np.float32)
        _enum(f, "laser_grid_format", GRID_FORMATS, "N_3")
        f["delta_t"] = np.float32(delta_t)
        f["t_start"] = np.float32(t_start)
        f["t_accounts_first_and_last_bounces"] = False
        f["scene_info"] = yaml.safe_dump({"original_format": "nlos_cl", "nlos_cl": ours})
    return path


def _enum(f, name, members, value):
    import h5py
    dtype = h5py.enum_dtype(members, basetype="i")
    ds = f.create_dataset(name, (1,), dtype=dtype)
    ds[0] = members[value]


# ---------------------------------------------------------------------------- reading

def read_capture(path) -> list[HistogramSet]:
    """One HistogramSet per laser point of a y-tal capture (the file is opened read-only).

    Where the file carries our own metadata (written by write_capture) and it agrees with the
    y-tal fields, the exact time axis and calibration are restored from it."""
    import h5py

    path = Path(path)
    require(path.is_file(), f"capture {path}", "does not exist", "pass the path of an .h5 file")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise InputError(f"capture {path}: not a readable HDF5 file ({exc}). Fix: pass an HDF5 "
                         "capture in y-tal's layout (truncated or corrupt files cannot be read)")
    with f:
        missing = [k for k in REQUIRED if k not in f]
        require(not missing, f"capture {path}", f"missing field(s) {missing}",
                "write every field of y-tal's NLOSCaptureData (see nlos_cl.capture)")
        fields = {k: _dataset(f, k, path) for k in f.keys()}
    return _to_histograms(fields, path)


def _dataset(f, key, path):
    import h5py
    obj = f[key]
    if not isinstance(obj, h5py.Dataset):
        raise InputError(f"capture {path}: field {key} is a group, not a dataset. Fix: write "
                         "it as y-tal does")
    if obj.shape is None:  # h5py.Empty: y-tal's None
        return None
    value = obj[()]
    if h5py.check_enum_dtype(obj.dtype) is not None:
        names = {v: k for k, v in h5py.check_enum_dtype(obj.dtype).items()}
        return names.get(int(np.ravel(value)[0]), "UNKNOWN")
    return value


def _enum_name(value, members, field, path):
    if isinstance(value, str):
        name = value
    else:
        arr = np.ravel(np.asarray(value))
        require(arr.size == 1 and np.issubdtype(arr.dtype, np.integer), f"capture {path}: {field}",
                f"expected an enum (integer), got {value!r}", "write y-tal's enum value")
        lookup = {v: k for k, v in members.items()}
        name = lookup.get(int(arr[0]), "UNKNOWN")
    require(name in members and name != "UNKNOWN", f"capture {path}: {field}",
            f"value {value!r} is not one of {[k for k in members if k != 'UNKNOWN']}",
            "write a known y-tal enum value")
    return name


def _float_array(value, field, path, last_dim=3):
    arr = np.asarray(value)
    require(np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer),
            f"capture {path}: {field}", f"has dtype {arr.dtype}, expected floating point",
            "store coordinates as float32 metres")
    arr = arr.astype(np.float64)
    require(arr.ndim >= 1 and arr.shape[-1] == last_dim, f"capture {path}: {field}",
            f"has shape {arr.shape}, expected (..., {last_dim})", "store (x, y, z) rows")
    require(bool(np.all(np.isfinite(arr))), f"capture {path}: {field}", "contains NaN or inf",
            "store finite coordinates")
    return arr


def _scalar(value, field, path):
    arr = np.ravel(np.asarray(value))
    require(arr.size == 1 and np.issubdtype(arr.dtype, np.number), f"capture {path}: {field}",
            f"expected one number, got {value!r}", "store a float32 scalar")
    x = float(arr[0])
    require(math.isfinite(x), f"capture {path}: {field}", f"is {x}", "store a finite number")
    return x


def _to_histograms(fields, path) -> list[HistogramSet]:
    import yaml

    h_format = _enum_name(fields["H_format"], H_FORMATS, "H_format", path)
    H = np.asarray(fields["H"])
    require(np.issubdtype(H.dtype, np.floating) or np.issubdtype(H.dtype, np.integer),
            f"capture {path}: H", f"has dtype {H.dtype}, expected float32 counts or power",
            "store H as float32")
    require(bool(np.all(np.isfinite(H))), f"capture {path}: H",
            f"{int(H.size - np.isfinite(H).sum())} values are NaN or inf",
            "replace missing bins by 0 before writing")
    sensors = _float_array(fields["sensor_grid_xyz"], "sensor_grid_xyz", path)
    lasers = _float_array(fields["laser_grid_xyz"], "laser_grid_xyz", path)
    delta_t = _scalar(fields["delta_t"], "delta_t", path)
    t_start = _scalar(fields["t_start"], "t_start", path)
    require(delta_t > 0, f"capture {path}: delta_t", f"must be positive, got {delta_t}",
            "store the bin width in metres of optical path")
    require(delta_t >= 1e-6, f"capture {path}: delta_t",
            f"is {delta_t:.3g}: that looks like seconds, but y-tal stores metres of optical path "
            f"(a 10 ps bin is {SPEED_OF_LIGHT * 10e-12:.4f} m)", "multiply delta_t and t_start by c")
    require(abs(t_start) < 1e5, f"capture {path}: t_start", f"is {t_start:.3g} m",
            "store t_start in metres of optical path")
    n_t = H.shape[0] if H.ndim else 0
    # Arrange H as (laser points, sensors, time).
    if h_format in ("T_Si", "T_Sx_Sy"):
        expect = (n_t,) + sensors.shape[:-1]
        require(H.shape == expect, f"capture {path}: H",
                f"has shape {H.shape}, but sensor_grid_xyz {sensors.shape} needs {expect}",
                "store H with the time axis first, then the sensor grid's shape")
        per_laser = [H.reshape(n_t, -1).T]
        laser_points = lasers.reshape(-1, 3)
        require(len(laser_points) == 1 or len(laser_points) != per_laser[0].shape[0]
                or not np.allclose(laser_points, sensors.reshape(-1, 3)),
                f"capture {path}: laser_grid_xyz",
                "is paired with the sensor grid (a confocal capture)",
                "nlos_cl needs one laser spot per set of histograms: use a non-confocal capture")
        require(len(laser_points) == 1, f"capture {path}: laser_grid_xyz",
                f"has {len(laser_points)} points for H_format {h_format}",
                "store one laser point, or use H_format T_Lx_Ly_Sx_Sy / T_Si_Li")
    elif h_format == "T_Lx_Ly_Sx_Sy":
        expect = (n_t,) + lasers.shape[:-1] + sensors.shape[:-1]
        require(H.shape == expect, f"capture {path}: H", f"has shape {H.shape}, expected {expect}",
                "store H as (T, Lx, Ly, Sx, Sy)")
        flat = H.reshape(n_t, -1, int(np.prod(sensors.shape[:-1])))
        per_laser = [flat[:, i, :].T for i in range(flat.shape[1])]
        laser_points = lasers.reshape(-1, 3)
    else:  # T_Si_Li
        expect = (n_t, int(np.prod(sensors.shape[:-1])), int(np.prod(lasers.shape[:-1])))
        require(H.shape == expect, f"capture {path}: H", f"has shape {H.shape}, expected {expect}",
                "store H as (T, Si, Li)")
        per_laser = [H[:, :, i].T for i in range(H.shape[2])]
        laser_points = lasers.reshape(-1, 3)
    spots = from_ytal(sensors.reshape(-1, 3))
    info = fields.get("scene_info")
    info = yaml.safe_load(info) if isinstance(info, (bytes, str)) else None
    ours = info.get("nlos_cl") if isinstance(info, dict) else None
    accounts = bool(np.ravel(np.asarray(fields["t_accounts_first_and_last_bounces"]))[0])
    sets = []
    for data, laser_ytal in zip(per_laser, laser_points):
        laser = from_ytal(laser_ytal)
        # hidden path of sample k = t_start + k delta_t - (first and last legs, if included)
        legs = np.zeros(len(spots))
        if accounts:
            require(fields.get("laser_xyz") is not None and fields.get("sensor_xyz") is not None,
                    f"capture {path}: laser_xyz", "t_accounts_first_and_last_bounces is set but "
                    "the device positions are missing", "store laser_xyz and sensor_xyz")
            lxyz = _float_array(fields["laser_xyz"], "laser_xyz", path).reshape(3)
            sxyz = _float_array(fields["sensor_xyz"], "sensor_xyz", path).reshape(3)
            legs = (np.linalg.norm(lxyz - laser_ytal)
                    + np.linalg.norm(sensors.reshape(-1, 3) - sxyz, axis=1))
        axis = TimeAxis((t_start - 0.5 * delta_t) / SPEED_OF_LIGHT, delta_t / SPEED_OF_LIGHT,
                        n_t)
        calibration = PathCalibration(SPEED_OF_LIGHT, -legs)
        truth, allow_negative = None, True
        if ours and len(per_laser) == 1:
            axis, calibration, truth, allow_negative = _restore(ours, axis, calibration)
        sets.append(HistogramSet(data.astype(np.float64), axis, spots, laser, calibration,
                                 truth=truth, allow_negative=allow_negative))
    return sets


def _restore(ours, axis, calibration):
    """Our exact axis and calibration, if they describe the same mapping as the y-tal fields."""
    try:
        t = ours["time_axis"]
        exact = TimeAxis(float(t["t0_s"]), float(t["dt_s"]), int(t["n_bins"]))
        c = ours["calibration"]
        exact_cal = PathCalibration(float(c["a_m_per_s"]), np.asarray(c["b_m"], float))
    except (KeyError, TypeError, ValueError, InputError):
        return axis, calibration, None, True
    ends = [0, -1]  # the hidden path at the first and last bin centre, for detector 0
    ours_path = exact_cal.a_m_per_s * exact.centres()[ends] + exact_cal.b_m[0]
    file_path = calibration.a_m_per_s * axis.centres()[ends] + calibration.b_m[0]
    # float32 fields round to ~1e-6 of their size; 0.1 mm is far below any bin
    same = exact.n_bins == axis.n_bins and np.allclose(ours_path, file_path, rtol=0, atol=1e-4)
    if not same:
        return axis, calibration, None, True
    truth = ours.get("truth")
    return exact, exact_cal, truth, bool(ours.get("allow_negative", True))
