"""Captures in y-tal's HDF5 layout (`tal.io.NLOSCaptureData`), read and written with h5py.

The field-by-field mapping, the frames and the safety rules are in docs/captures.md. In short:
H is time-first (T_Si, T_Sx_Sy, T_Lx_Ly_Sx_Sy, T_Li_Si), delta_t and t_start are metres of
optical path, our metadata rides in scene_info['nlos_cl'], and y-tal's frame (wall Z = 0) maps
to ours by (x, y, z) = (-X, Z, Y) (a wall elsewhere: a frame fitted to its points, wall.py). Writes are atomic; reads check truncation, sizes and
geometry. Pairings follow y-tal (pairing.py): one laser point -> one set; paired or confocal
(one laser point per sensor point) -> one set with a laser spot per histogram; exhaustive
(T_Lx_Ly_Sx_Sy, T_Li_Si) -> one set per laser point, or with joint=True one paired set.
"""
from __future__ import annotations

import io
from pathlib import Path

from ...core.errors import InputError, require
from ...core.histograms import HistogramSet
from .checks import unreadable
from .fields import (  # noqa: F401  (the enums, for users)
    FIELDS,
    GRID_FORMATS,
    H_FORMATS,
    REQUIRED,
    check_complete,
    check_memory,
    check_regular,
    check_storage,
    check_writable,
    dataset,
    is_capture,
    to_histograms,
    write_fields,
)
from .frames import YTAL, CaptureFrame, check_wall_spots, from_ytal, to_ytal  # noqa: F401


def write_capture(path, histograms: HistogramSet, *, device_distance_m: float = 20.0,
                  metadata: dict | None = None, compression: int = 4, force: bool = False
                  ) -> Path:
    """Write one HistogramSet as a y-tal capture (H_format T_Si, sensor grid N_3); one t_start
    for all sensors. A paired set (laser_spot (N, 3)) gets one laser_grid_xyz row per
    histogram, so y-tal reads it as is_laser_paired_to_sensor (is_confocal where laser =
    detector point). A confocal scan on a regular grid is written as y-tal writes its grids
    (T_Sx_Sy, X_Y_3: grid_write; read back in the grid's row order), so that y-tal's grid
    reconstructions take it. Our exact time axis, calibration, truth and `metadata` ride in
    scene_info['nlos_cl']. Atomic (see nlos_cl.io.safe_write.atomic_write: Ctrl-C leaves the old file,
    a concurrent writer's file is never silently lost); a non-capture file needs force=True."""
    import h5py

    from ..safe_write import atomic_write
    from .grid_write import scan_grid, write_grid_capture

    h = histograms
    check_writable(h, device_distance_m)
    grid = scan_grid(h)
    if grid is not None:
        return write_grid_capture(path, h, grid, device_distance_m=device_distance_m,
                                  metadata=metadata, compression=compression, force=force)

    def write(tmp):
        # built in memory, then written as plain bytes: a full disk is then an OSError that
        # atomic_write reports (HDF5 writing to a full disk ended in a segfault); the image is
        # the size of the data already in memory
        image = io.BytesIO()
        with h5py.File(image, "w") as f:
            write_fields(f, h, device_distance_m, metadata, compression)
        with open(tmp, "wb") as fh:
            fh.write(image.getbuffer())
    return atomic_write(path, write, keep_unless=is_capture, force=force, record=False,
                        what="capture",
                        kind="an HDF5 capture (nlos_cl's or y-tal's)")


def write_scan(path, h: HistogramSet, *, metadata: dict | None = None, force: bool = False
               ) -> tuple:
    """write_capture's file (a confocal grid scan as a y-tal grid capture, anything else
    T_Si); (the path, the grid or None)."""
    from .grid_write import scan_grid
    return write_capture(path, h, metadata=metadata, force=force), scan_grid(h)


def read_capture(path, *, max_bytes: int | None = None, joint: bool = False
                 ) -> list[HistogramSet]:
    """The HistogramSets of a y-tal capture (the file is opened read-only): one for a single
    laser point, and one paired set (laser_spot (N, 3)) for a paired or confocal capture; an
    exhaustive capture (laser grid x sensor grid) gives one set per laser point, or with
    `joint=True` one paired set of every laser/sensor pair (row i * S + j: laser i, sensor j).
    Our own metadata (from write_capture), where it agrees with the y-tal fields, restores the
    exact time axis and calibration. `max_bytes`: memory H may take (default half of RAM)."""
    return read_capture_with_frame(path, max_bytes=max_bytes, joint=joint)[0]


def read_capture_with_frame(path, *, max_bytes: int | None = None, joint: bool = False
                            ) -> tuple[list[HistogramSet], CaptureFrame]:
    """read_capture's sets (internal frame) and the file's own frame (YTAL, or the one fitted to
    a wall that is not Z = 0: wall.capture_frame), to give and report positions, grids and
    regions in the file's coordinates."""
    import h5py

    path = Path(path)
    where = f"capture {path}"
    check_regular(path)
    check_complete(path)
    try:
        with h5py.File(path, "r") as f:
            check_storage(f, path)  # before any field is looked up: links resolve on lookup
            missing = [k for k in REQUIRED if k not in f]
            require(not missing, where, f"missing field(s) {missing}",
                    "write every field of y-tal's NLOSCaptureData (see nlos_cl.io.ytal.capture)")
            require(isinstance(f["H"], h5py.Dataset), f"{where}: H", "is a group, not a "
                    "dataset", "store H as one array (time first), as y-tal writes it")
            require("frame_t_s" not in f, where, "is a sequence of frames (it has "
                    "frame_t_s), not one capture", "track it with `nlos-cl track`, or "
                    "nlos_cl.tracking.read_sequence(path)[k] for frame k")
            check_memory(f, path, max_bytes)
            fields = {k: dataset(f, k, path) for k in FIELDS if k in f}
            sets, frame = to_histograms(fields, f["H"], path, joint=joint, with_frame=True)
    except InputError:
        raise
    except (OSError, RuntimeError, LookupError, ValueError, TypeError, AttributeError,
            OverflowError) as exc:  # h5py on corrupted bytes raises all of these
        raise unreadable(exc, path) from None
    return sets, frame
