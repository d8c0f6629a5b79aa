"""The relay wall of a capture whose wall points are not the plane Z = 0 (y-tal's): a plane
fitted through the laser and sensor points, its front from what the file says, and the
CaptureFrame that puts it at our y = 0; the device legs (first_and_last_legs) and the check of
stored coordinates (float_array).

- plane: through the points' centroid, normal to the stored wall normals where every laser and
  sensor point is within WALL_TOLERANCE_M of that plane (what the file declares; a least-squares
  plane through 8 spots jittered by 3 cm tilts by up to 2 deg, and the upright shapes of the
  default estimator with it), else the least-squares plane (SVD). Points within
  WALL_TOLERANCE_M of one line (or of one point) fix no plane: then it holds that line and the
  direction the file's normals give (else the devices', else y-tal's +Z).
- front (our hidden side y > 0): the side the stored wall normals (sensor_grid_normals,
  laser_grid_normals) point to; else the side of the devices (laser_xyz, sensor_xyz), which see
  the wall's front as the hidden scene does; else y-tal's convention, the side of +Z (the
  normal nearest +Z).
- in-plane axes: y-tal's (x, z) = (-X, Y) carried by the smallest rotation taking Z to the
  normal; collinear points then turn about the normal onto the nearer of x and z (their unseen
  axis is then the other one, as for a line on Z = 0: localization.region.unseen_axis).
- origin: the (first) laser point, put on the plane: the frame then moves with the points
  (cells of the default region sit on whole steps from it), as YTAL's origin does for our
  captures, whose laser spot is nlos_cl's O = (0, 0, 0).
Points off the plane are used as they are (the ellipse path |c - O| + |c - D| needs no plane);
frames.check_wall_spots refuses a wall that no plane fits within WALL_TOLERANCE_M.
"""
from __future__ import annotations

import math

import numpy as np

from ...core.errors import require
from .checks import flag
from .frames import ON_PLANE_Z_M, WALL_TOLERANCE_M, YTAL, CaptureFrame, _fmt

AGREE_COS = math.cos(math.radians(45))  # stored normals nearer the plane than its normal: wrong
_EX, _EY, _EZ = np.eye(3)


def capture_frame(fields: dict, sensors, lasers, path) -> CaptureFrame:
    """The frame of a capture's fields (file coordinates; sensors and lasers (n, 3)): YTAL while
    every wall point is within ON_PLANE_Z_M of Z = 0 and nothing in the file puts the hidden
    side at Z < 0 (what was read before, exactly); else the fitted wall's."""
    where = f"capture {path}"
    pts = np.vstack([np.reshape(lasers, (-1, 3)), np.reshape(sensors, (-1, 3))])
    normal, named = _stored_normal(fields)
    devices = {k: p for k in ("laser_xyz", "sensor_xyz")
               if (p := _point(fields.get(k))) is not None}
    if float(np.abs(pts[:, 2]).max()) <= ON_PLANE_Z_M:
        votes = _votes(_EZ, np.zeros(3), normal, devices, named)
        if not votes or {s for s, _ in votes} != {-1}:  # as before, unless all say Z < 0
            return YTAL
        return _frame(-_EZ, np.zeros(3), None, f"from {votes[0][1]}")
    centre = pts.mean(axis=0)
    n, line = _plane(pts - centre, normal, [p - centre for p in devices.values()])
    if normal is not None:
        _check_normal(pts, centre, n, normal, named, len(np.reshape(lasers, (-1, 3))), where)
    votes = _votes(n, centre, normal, devices, named)
    require(len({s for s, _ in votes}) <= 1, f"{where}: {votes[-1][1] if votes else ''}",
            f"puts the hidden side on the other side of the wall from {votes[0][1] if votes else ''}"
            " (the laser and the sensor see the wall's front, as the hidden scene does)",
            "store the device positions and wall normals on the wall's front side")
    side, why = (votes[0][0], f"from {votes[0][1]}") if votes else (
        -1 if n @ _EZ < 0 else 1, "y-tal's convention: the side of +Z")
    laser = pts[0] - ((pts[0] - centre) @ n) * n
    return _frame(n * side, laser, line, why)


def _check_normal(pts, centre, n, normal, named, n_lasers, where) -> None:
    """Refuse wall points whose plane is more than 45 deg from the stored normals, naming the
    point farthest off the wall the normals describe (one wrong point, or wrong normals)."""
    c = min(abs(float(normal @ n)), 1.0)
    off = np.abs((pts - centre) @ normal)
    k = int(np.argmax(off))
    field, i = ("laser_grid_xyz", k) if k < n_lasers else ("sensor_grid_xyz", k - n_lasers)
    require(c >= AGREE_COS, f"{where}: {field}", f"point {i} {_fmt(pts[k])} lies {off[k]:.3g} m "
            f"off the relay wall that {named} describe (normal {_fmt(normal)} through the "
            f"points' centre), and the points' own plane is {math.degrees(math.acos(c)):.0f} deg "
            "from it", f"store the points of one flat wall, and its normals in {named}")


def _plane(centred, normal, hints):
    """(unit normal, line direction or None) of the wall through the centred points: the stored
    normal's plane where they all fit it, else the least-squares plane; where they lie within
    WALL_TOLERANCE_M of a line (or a point), the plane through it nearest the stored normal
    (then the first usable hint, then Z, Y, X)."""
    _, vecs = np.linalg.eigh(centred.T @ centred)  # ascending: normal first, line last
    line = vecs[:, 2]
    along = centred @ line
    if np.linalg.norm(centred - np.outer(along, line), axis=1).max() > WALL_TOLERANCE_M:
        fits = normal is not None and np.abs(centred @ normal).max() <= WALL_TOLERANCE_M
        return (normal, None) if fits else (vecs[:, 0], None)
    line = line if np.ptp(along) > WALL_TOLERANCE_M else None
    for h in [h for h in [normal] + hints if h is not None] + [_EZ, _EY, -_EX]:
        size = float(np.linalg.norm(h))
        h = h - (h @ line) * line if line is not None else h
        if size > 0 and np.linalg.norm(h) >= 0.5 * size:  # 30 deg or more off the line
            return h / np.linalg.norm(h), line
    raise AssertionError("unreachable: Z or Y is 30 deg off any line")


def _votes(n, centre, normal, devices, named) -> list:
    """[(+1 or -1, field)]: the side of normal n each of the file's clues puts the hidden
    space (the stored normals where they are within 45 deg of n; each device farther than
    WALL_TOLERANCE_M from the wall)."""
    votes = []
    if normal is not None and abs(float(normal @ n)) >= AGREE_COS:
        votes.append((1 if normal @ n > 0 else -1, named))
    for key, p in devices.items():
        d = float((p - centre) @ n)
        if abs(d) > WALL_TOLERANCE_M:
            votes.append((1 if d > 0 else -1, key))
    return votes


def _frame(n, origin, line, why) -> CaptureFrame:
    """The frame whose y is n, x and z y-tal's carried by the smallest rotation Z -> n."""
    c = float(n @ _EZ)
    if c < -1 + 1e-12:  # facing -Z: half a turn about Y keeps Y up
        rot = np.diag([-1.0, 1.0, -1.0])
    else:
        v = np.cross(_EZ, n)
        k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
        rot = np.eye(3) + k + k @ k / (1 + c)
    m = np.asarray(YTAL.matrix) @ rot.T
    if line is not None:  # turn about y onto the nearer of x and z
        u = m @ line
        phi = math.atan2(u[2], u[0])
        d = phi - round(phi / (math.pi / 2)) * (math.pi / 2)
        turn = np.array([[math.cos(d), 0, math.sin(d)], [0, 1, 0],
                         [-math.sin(d), 0, math.cos(d)]])
        m = turn @ m
    return CaptureFrame("ytal (fitted wall)", ("X", "Y", "Z"), m,
                        f"the capture file's frame; its relay wall is the plane fitted through "
                        f"the wall points, through {_fmt(origin)} with normal {_fmt(m[1])} "
                        f"towards the hidden side ({why}); nlos_cl's internal (x, y, z) = "
                        "to_internal @ (file - origin), y-tal's (-X, Z, Y) turned onto the wall",
                        origin)


def _stored_normal(fields):
    """(the mean stored wall normal, unit, or None where absent or inconsistent; its field)."""
    rows, named = [], None
    for key in ("sensor_grid_normals", "laser_grid_normals"):
        arr = _numbers(fields.get(key))
        if arr is None or arr.size % 3:
            continue
        arr = arr.reshape(-1, 3)
        norm = np.linalg.norm(arr, axis=1)
        if np.any(norm > 0):
            rows.append(arr[norm > 0] / norm[norm > 0, None])
            named = named or key
    if not rows:
        return None, None
    mean = np.vstack(rows).mean(axis=0)
    # normals that point every way say nothing about one wall
    return (mean / np.linalg.norm(mean), named) if np.linalg.norm(mean) >= 0.5 else (None, None)


def _point(value):
    arr = _numbers(value)
    return arr.reshape(3) if arr is not None and arr.size == 3 else None


def _numbers(value):
    """A finite float array, or None for what is absent, empty or not numbers (optional fields
    nlos_cl never needed before: unusable means unknown, not an error)."""
    if value is None:
        return None
    arr = np.asarray(value)
    if arr.size == 0 or not (np.issubdtype(arr.dtype, np.floating)
                             or np.issubdtype(arr.dtype, np.integer)):
        return None
    arr = arr.astype(np.float64)
    return arr if bool(np.all(np.isfinite(arr))) else None


def ours_in(frame: CaptureFrame, points):
    """Points our metadata holds (truths: internal coordinates of YTAL, as write_capture stores
    them) in `frame`'s internal coordinates."""
    if points is None or frame is YTAL:
        return points
    return frame.to_internal(YTAL.from_internal(np.asarray(points, dtype=np.float64)))


def first_and_last_legs(fields, sensors, lasers, path):
    """Per sensor point and per laser point (y-tal frame, flattened), the device legs to
    remove when t_accounts_first_and_last_bounces is set; zeros otherwise. Device origins
    stored empty (h5py.Empty, y-tal's None, or a 0-size array) are unknown, not an error,
    unless these legs need them."""
    legs = np.zeros(len(sensors)), np.zeros(len(lasers))
    if not flag(fields["t_accounts_first_and_last_bounces"], "t_accounts_first_and_last_bounces",
                path):
        return legs
    lxyz, sxyz = (origin(fields.get(k)) for k in ("laser_xyz", "sensor_xyz"))
    require(lxyz is not None and sxyz is not None, f"capture {path}: laser_xyz",
            "t_accounts_first_and_last_bounces is set but the device positions are missing",
            "store laser_xyz and sensor_xyz")
    lxyz, sxyz = (float_array(v, k, path) for v, k in ((lxyz, "laser_xyz"),
                                                        (sxyz, "sensor_xyz")))
    for value, key in ((lxyz, "laser_xyz"), (sxyz, "sensor_xyz")):
        require(value.size == 3, f"capture {path}: {key}", f"has shape {value.shape}, expected "
                "one (x, y, z) point: the device's position", f"store {key} as 3 numbers")
    lxyz, sxyz = lxyz.reshape(3), sxyz.reshape(3)
    return np.linalg.norm(sensors - sxyz, axis=1), np.linalg.norm(lasers - lxyz, axis=1)


def origin(value):
    """A device origin as stored, or None where it is empty (unknown)."""
    return None if value is None or np.size(value) == 0 else value


def float_array(value, field, path, last_dim=3):
    arr = np.asarray(value)
    require(np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer),
            f"capture {path}: {field}", f"has dtype {arr.dtype}, expected floating point",
            "store coordinates as float32 metres")
    require(arr.ndim >= 1 and arr.shape[-1] == last_dim, f"capture {path}: {field}",
            f"has shape {arr.shape}, expected (..., {last_dim})", "store (x, y, z) rows")
    require(bool(np.all(np.isfinite(arr))), f"capture {path}: {field}", "contains NaN or inf",
            "store finite coordinates")
    return arr.astype(np.float64)
