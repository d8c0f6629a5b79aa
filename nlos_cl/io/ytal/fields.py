"""The fields of y-tal's HDF5 layout (`tal.io.NLOSCaptureData`) that captures and sequences
share: the format enums, writing one frame's fields, and reading them back checked (truncation,
memory, types, geometry) into HistogramSets. docs/captures.md has the field-by-field mapping."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ...core.constants import SPEED_OF_LIGHT
from ...core.errors import InputError, require, shown
from ...core.histograms import HistogramSet, PathCalibration, TimeAxis
from .checks import check_bin, check_wall_scale, flag, our_metadata, unreadable
from .frames import check_wall_spots, to_ytal
from .pairing import check_h_format, plan, read_block
from .wall import capture_frame, first_and_last_legs, float_array, ours_in

H_FORMATS = {"UNKNOWN": 0, "T_Sx_Sy": 1, "T_Lx_Ly_Sx_Sy": 2, "T_Si": 3, "T_Li_Si": 4}


GRID_FORMATS = {"UNKNOWN": 0, "N_3": 1, "X_Y_3": 2}


REQUIRED = ("H", "H_format", "sensor_grid_xyz", "laser_grid_xyz", "delta_t", "t_start",
            "t_accounts_first_and_last_bounces")


# the fields other than H that readers use (and read in full); any other dataset is left unread
FIELDS = REQUIRED[1:] + ("sensor_grid_format", "laser_grid_format", "scene_info", "laser_xyz",
                         "sensor_xyz", "sensor_grid_normals", "laser_grid_normals")


HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def write_fields(f, h: HistogramSet, device_distance_m, metadata, compression):
    from ..yamlfile import dump_json_yaml

    a, axis = h.calibration.a_m_per_s, h.time_axis
    offsets = h.calibration.offsets(h.n_detectors)
    spots, laser = to_ytal(h.detector_spots), to_ytal(h.laser_spot)
    wall_normal = to_ytal([0.0, 1.0, 0.0])
    ours = {"format_version": 1,
            "time_axis": {"t0_s": axis.t0_s, "dt_s": axis.dt_s, "n_bins": axis.n_bins},
            "calibration": {"a_m_per_s": a, "b_m": [float(b) for b in h.calibration.b_m]},
            "truth": None if h.truth is None else [float(v) for v in h.truth],
            "truths": None if h.truths is None else [[float(v) for v in t] for t in h.truths],
            "allow_negative": bool(h.allow_negative), "units": "W",
            "frame": "nlos_cl (x, y, z) = (-X, Z, Y) of this file"}
    if metadata:
        ours["metadata"] = metadata
    f.create_dataset("H", data=np.ascontiguousarray(h.data.T, dtype=np.float32),
                     compression="gzip" if compression else None,
                     compression_opts=compression or None)
    enum(f, "H_format", H_FORMATS, "T_Si")
    f["sensor_xyz"] = (spots.mean(axis=0) + device_distance_m * wall_normal).astype(np.float32)
    f["sensor_grid_xyz"] = spots.astype(np.float32)
    f["sensor_grid_normals"] = np.tile(wall_normal, (h.n_detectors, 1)).astype(np.float32)
    enum(f, "sensor_grid_format", GRID_FORMATS, "N_3")
    # paired: one laser point per sensor point, in the sensor grid's shape and format, which is
    # what y-tal's is_laser_paired_to_sensor() (and is_confocal(), laser = sensor) checks
    laser = laser.reshape(-1, 3)
    f["laser_xyz"] = (laser.mean(axis=0) + device_distance_m * wall_normal).astype(np.float32)
    f["laser_grid_xyz"] = laser.astype(np.float32)
    f["laser_grid_normals"] = np.tile(wall_normal, (len(laser), 1)).astype(np.float32)
    enum(f, "laser_grid_format", GRID_FORMATS, "N_3")
    f["delta_t"] = np.float32(a * axis.dt_s)
    f["t_start"] = np.float32(a * (axis.t0_s + 0.5 * axis.dt_s) + offsets[0])  # bin centre 0
    f["t_accounts_first_and_last_bounces"] = False
    # YAML as JSON (y-tal reads it with PyYAML; nlos_cl without it: nlos_cl.io.yamlfile)
    f["scene_info"] = dump_json_yaml({"original_format": "nlos_cl", "nlos_cl": ours})


def enum(f, name, members, value):
    import h5py
    f.create_dataset(name, (1,), dtype=h5py.enum_dtype(members, basetype="i"))[0] = members[value]


def is_capture(path: Path) -> bool:
    """Whether `path` is a regular file holding a capture's H and H_format (a FIFO or device is
    not: opening one could block or consume it)."""
    import h5py

    from ...core.gate import open_regular
    try:
        with open_regular(path, f"{path}", "") as fh:
            if fh.read(8) != HDF5_SIGNATURE:
                return False
        with h5py.File(path, "r") as f:
            return "H" in f and "H_format" in f
    except Exception:  # noqa: BLE001 - anything unreadable is not a capture
        return False


def check_complete(path: Path) -> None:
    """An HDF5 superblock declares the file's end (base + EOF address): a shorter file was cut
    off. Superblock versions 0-1 hold it after 24/28 bytes and 2 offsets, 2-3 after 12."""
    import os

    from ...core.gate import open_regular
    where = f"capture {path}"
    with open_regular(path, where, "pass the path of an .h5 file") as fh:
        size, head = os.fstat(fh.fileno()).st_size, fh.read(4096)
    version = head[:19].decode("ascii", "replace") + (": HDF5 inside" * (b"7.3" in head[:20]))
    require(not head.startswith(b"MATLAB"), where, f"is a MATLAB .mat file ({version}), not a "
            "y-tal capture", "convert it first: nlos-cl convert FILE.mat --out F.h5 "
            "(nl.read_dataset reads the formats it knows: lct, fk, ccsocr, keyhole)")
    base = next((b for b in (0, 512, 1024, 2048) if head[b:b + 8] == HDF5_SIGNATURE), None)
    require(base is not None or (size >= 8 and not HDF5_SIGNATURE.startswith(head[:8])), where,
            f"incomplete or corrupted file: {size} bytes, shorter than an HDF5 header",
            "copy or write the capture again")
    require(base is not None, where, "not an HDF5 file (no HDF5 signature)",
            "pass a capture in y-tal's HDF5 layout")
    padded = head + bytes(64)  # a file cut inside the superblock reads as zeros there
    version = head[base + 8] if len(head) > base + 8 else -1
    o = padded[base + 13] if version in (0, 1) else padded[base + 9] if version in (2, 3) else 0
    start = base + {0: 24, 1: 28, 2: 12, 3: 12}.get(version, 0)
    end = [int.from_bytes(head[start + i * o:start + (i + 1) * o], "little") for i in (0, 2)]
    # the end of file address counts from the file's first byte, a user block included (HDF5
    # library files, MATLAB v7.3's 512-byte header): base + EOF would count the block twice
    require(o in (2, 4, 8) and len(head) >= start + 3 * o and size >= end[1], where,
            f"incomplete or corrupted file: its HDF5 header declares {end[1] if o else '?'} "
            f"bytes but the file has {size} (cut off by an interrupted copy, download or write)",
            "copy or write the capture again")


def check_regular(path: Path, what: str = "capture") -> None:
    """A capture is a regular file (the input gate's rule, nlos_cl.core.gate): a FIFO would
    block the read (forever, if nobody writes), a device would be read without end, a folder
    is no capture."""
    from ...core.gate import regular_size
    regular_size(path, f"{what} {path}", "pass the path of an .h5 file (copy a stream to a "
                 "file first)")


def check_storage(f, path, what: str = "capture") -> None:
    """Every link in the file is data stored in it (nlos_cl.io.hdf5_gate.check_links): an HDF5
    external or soft link resolves to another file or object, external raw storage reads the
    bytes of any file named in the capture (H pointed at /etc/passwd or ~/.ssh/id_rsa), and a
    virtual dataset maps other files in. y-tal writes none of these."""
    from ..hdf5_gate import check_links
    check_links(f, f"{what} {path}", what)


def check_memory(f, path, max_bytes, what: str = "capture", frames: bool = False) -> None:
    """What the reader will hold, through the input gate (nlos_cl.io.hdf5_gate.check_budget),
    before anything is read: H as float64 (8 bytes a value) beside its slice as stored (for a
    sequence one frame at a time, and one frame's truths), the fields read as stored; each
    compressed chunk's expansion too. Fields nlos_cl does not read are not counted (nor read)."""
    from ..hdf5_gate import Read, check_budget
    row = 1 if frames else None
    reads = {"H": Read(8, row), **{k: Read() for k in FIELDS},
             **({"frame_t_s": Read(), "frame_truths": Read(0, 1)} if frames else {})}
    check_budget(f, f"{what} {path}", reads, max_bytes, f"crop the {what} (fewer bins or "
                 "sensor points), or read it on a machine with more memory")


def dataset(f, key, path):
    import h5py
    obj = f[key]
    if not isinstance(obj, h5py.Dataset):
        raise InputError(f"capture {path}: field {key} is a group, not a dataset. Fix: write "
                         "it as y-tal does")
    if obj.shape is None:  # h5py.Empty: y-tal's None
        return None
    try:
        value, members = obj[()], h5py.check_enum_dtype(obj.dtype)
    except (OSError, RuntimeError, ValueError, TypeError) as exc:
        raise unreadable(exc, path, key, dataset=obj) from None
    if members is not None:  # the stored number: y-tal's names changed (T_Si_Li -> T_Li_Si)
        return int(np.ravel(value)[0])
    return value


def enum_name(value, members, field, path):
    name, arr = value, np.ravel(np.asarray(value))
    if not isinstance(value, str):
        require(arr.size == 1 and np.issubdtype(arr.dtype, np.integer), f"capture {path}: {field}",
                f"expected an enum (integer), got {shown(value)}", "write y-tal's enum value")
        name = {v: k for k, v in members.items()}.get(int(arr[0]), "UNKNOWN")
    require(name in members and name != "UNKNOWN", f"capture {path}: {field}",
            f"value {shown(value)} is not one of {[k for k in members if k != 'UNKNOWN']}",
            "write a known y-tal enum value")
    return name


def scalar(value, field, path):
    arr = np.ravel(np.asarray(value))
    require(arr.size == 1 and np.issubdtype(arr.dtype, np.number), f"capture {path}: {field}",
            f"expected one number, got {shown(value)}", "store a float32 scalar")
    x = float(arr[0])
    require(math.isfinite(x), f"capture {path}: {field}", f"is {x}", "store a finite number")
    return x


def to_histograms(fields, H, path, joint=False, with_frame=False):
    """[HistogramSet] (with_frame: and the file's CaptureFrame, wall.capture_frame). H (unread):
    shapes are checked first, then it is read one HistogramSet at a time (one laser point at a
    time for exhaustive captures; see pairing.py for y-tal's pairings)."""
    where = f"capture {path}"
    check_h_format(fields["H_format"], H, path)
    h_format = enum_name(fields["H_format"], H_FORMATS, "H_format", path)
    require(H.shape is not None and (np.issubdtype(H.dtype, np.floating)
            or np.issubdtype(H.dtype, np.integer)), f"{where}: H",
            f"has dtype {H.dtype} (shape {H.shape}), expected float32 counts or power",
            "store H as float32")
    sensors = float_array(fields["sensor_grid_xyz"], "sensor_grid_xyz", path)
    lasers = float_array(fields["laser_grid_xyz"], "laser_grid_xyz", path)
    check_wall_scale(sensors, "sensor_grid_xyz", path)
    check_wall_scale(lasers, "laser_grid_xyz", path)
    formats = tuple(fields.get(k) for k in ("sensor_grid_format", "laser_grid_format"))
    blocks = plan(h_format, H.shape, sensors, lasers, formats, path, joint)
    axis = time_axis(fields, H.shape[0], path)
    sensors, lasers = sensors.reshape(-1, 3), lasers.reshape(-1, 3)
    frame = capture_frame(fields, sensors, lasers, path)
    spots, laser_points = frame.to_internal(sensors), frame.to_internal(lasers)
    paired = blocks[0].paired and not joint  # joint rows: the grids are checked unpaired
    check_wall_spots(laser_points, spots, frame, paired=paired, laser_field="laser_grid_xyz",
                     spots_field="sensor_grid_xyz", prefix=f"{where}: ")
    legs = first_and_last_legs(fields, sensors, lasers, path)
    ours = our_metadata(fields.get("scene_info"), path) if len(blocks) == 1 else None
    sets = []
    for i, block in enumerate(blocks):
        try:
            data = read_block(H, block)
        except (OSError, RuntimeError) as exc:  # a lock, a missing filter, cut-off chunks
            raise unreadable(exc, path, "H", dataset=H) from None
        bad = int(data.size - np.count_nonzero(np.isfinite(data)))
        require(bad == 0, f"{where}: H", f"{bad} values are NaN or inf"
                + (f" (laser point {i})" if len(blocks) > 1 else ""),
                "replace missing bins by 0 before writing")
        calibration = PathCalibration(SPEED_OF_LIGHT, -(legs[0][block.sensors]
                                                        + legs[1][block.lasers]))
        exact = restore(ours, axis, calibration, path) if ours else (axis, calibration, None,
                                                                     True, None)
        laser = laser_points[block.lasers] if block.paired else laser_points[block.lasers[0]]
        sets.append(HistogramSet(data, exact[0], spots[block.sensors], laser, exact[1],
                                 truth=ours_in(frame, exact[2]), allow_negative=exact[3],
                                 truths=ours_in(frame, exact[4])))
    return (sets, frame) if with_frame else sets


def time_axis(fields, n_t, path) -> TimeAxis:
    """y-tal's delta_t and t_start (metres of optical path; t_start is bin 0's centre)."""
    where = f"capture {path}"
    delta_t = scalar(fields["delta_t"], "delta_t", path)
    t_start = scalar(fields["t_start"], "t_start", path)
    require(delta_t > 0, f"{where}: delta_t", f"must be positive, got {delta_t}",
            "store the bin width in metres of optical path")
    require(delta_t >= 1e-6, f"{where}: delta_t", f"is {delta_t:.3g}: that looks like seconds, "
            f"but y-tal stores metres of optical path (a 10 ps bin is {SPEED_OF_LIGHT * 1e-11:.4f}"
            " m)", "multiply delta_t and t_start by c")
    require(abs(t_start) < 1e5, f"{where}: t_start", f"is {t_start:.3g} m",
            "store t_start in metres of optical path")
    check_bin(delta_t, path)
    return TimeAxis((t_start - 0.5 * delta_t) / SPEED_OF_LIGHT, delta_t / SPEED_OF_LIGHT,
                    n_t)


def restore(ours, axis, calibration, path=""):
    """Our exact axis and calibration, if they describe the same mapping as the y-tal fields."""
    try:
        t = ours["time_axis"]
        exact = TimeAxis(float(t["t0_s"]), float(t["dt_s"]), int(t["n_bins"]))
        c = ours["calibration"]
        exact_cal = PathCalibration(float(c["a_m_per_s"]), np.asarray(c["b_m"], float))
    except (KeyError, TypeError, ValueError, InputError):
        return axis, calibration, None, True, None
    ends = [0, -1]  # the hidden path at the first and last bin centre, for detector 0; float32
    ours_path = exact_cal.a_m_per_s * exact.centres()[ends] + exact_cal.b_m[0]  # fields round
    file_path = calibration.a_m_per_s * axis.centres()[ends] + calibration.b_m[0]  # ~1e-6 rel
    if exact.n_bins != axis.n_bins or not np.allclose(ours_path, file_path, rtol=0, atol=1e-4):
        return axis, calibration, None, True, None
    truth = ours.get("truth")
    require(truth is None or _is_point(truth), f"capture {path}: scene_info nlos_cl.truth",
            f"expected [x, y, z] or null, got {shown(truth)}", "write it again with nl.write_capture")
    negative = flag(ours.get("allow_negative", True), "scene_info nlos_cl.allow_negative", path)
    return exact, exact_cal, truth, negative, stored_truths(ours, truth, path)


def _is_point(value) -> bool:
    return isinstance(value, list) and len(value) == 3 and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)


def stored_truths(ours, truth, path=""):
    """Every target's centre (K, 3), ours: `truths` as written since every target's is kept;
    files written before keep `metadata.targets` (`nlos-cl simulate`'s) where its first is the
    truth, else nothing beyond `truth` (None)."""
    truths, field = ours.get("truths"), "truths"
    if truths is None:  # an older file: nlos-cl simulate's metadata, where it agrees
        meta = ours.get("metadata")
        old = meta.get("targets") if isinstance(meta, dict) else None
        if not (isinstance(old, list) and old and all(_is_point(t) for t in old)
                and truth is not None and np.allclose(old[0], truth)):
            return None
        truths, field = old, "metadata.targets"
    require(isinstance(truths, list) and bool(truths) and all(map(_is_point, truths)),
            f"capture {path}: scene_info nlos_cl.{field}", f"expected a list of [x, y, z], got "
            f"{shown(truths)}", "write it again with nl.write_capture")
    return np.asarray(truths, dtype=np.float64)


def check_writable(h: HistogramSet, device_distance_m) -> None:
    """What a y-tal capture can hold: one t_start for all detectors, a positive distance."""
    offsets = h.calibration.offsets(h.n_detectors)
    require(bool(np.allclose(offsets, offsets[0], rtol=0, atol=1e-9)), "calibration.b_m",
            "differs between detectors, but a y-tal capture has a single t_start",
            "write one file per group of detectors that share an offset")
    require(isinstance(device_distance_m, (int, float)) and 0 < device_distance_m < math.inf,
            "device_distance_m", f"must be a positive distance, got {shown(device_distance_m)}", "20.0")
