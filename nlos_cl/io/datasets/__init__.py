"""Readers for measured datasets as their authors publish them (MATLAB .mat files, folders),
one module per format, each returning a HistogramSet in nlos_cl's internal frame (relay wall
y = 0, hidden space y > 0, z up). `nlos-cl convert` writes what they return as a y-tal capture.

| format | what it is | module |
|---|---|---|
| `ccsocr` | a folder with sub_Sig.mat, C_i.mat, C_d.mat (CC-SOCR, Liu et al. 2023): N lasers, one detector | ccsocr.py |
| `lct` | a .mat with rect_data (Nx, Ny, T) and width (LCT, O'Toole et al. 2018): confocal | lct.py |
| `fk` | a meas_*.mat (N, N, T) with its tof.mat, or their folder (f-k migration, Lindell et al. 2019): confocal, rectified by tofgrid | fk.py |
| `fk-interactive` | the same with a 4-D meas (F, N, N, T): a sequence of confocal frames (f-k's interactive captures) | fk.py |
| `consumer-nlos` | a folder of volume_*.npz frames (Somasundaram et al. 2026): a sequence of confocal frames | consumer_nlos.py |
| `keyhole` | a folder with scan_*.mat, direct_after.mat, LongExpNoObject_after.mat (Metzler et al. 2021): a sequence of one confocal spot, range only (localization.ranges) | keyhole.py |

A sequence format (consumer-nlos, keyhole, fk-interactive) returns (frames, metadata): frames a
list of (t_s, HistogramSet[, truths]) that write_sequence takes, metadata what the file keeps
beside them (consumer-nlos with static=True pools its frames into one HistogramSet instead: a
moving sensor).
"""
from __future__ import annotations

import importlib
import inspect
from pathlib import Path

import numpy as np

from ...core.errors import require

FORMATS = {"ccsocr": "ccsocr:read_ccsocr", "lct": "lct:read_lct",
           "consumer-nlos": "consumer_nlos:read_consumer_nlos", "keyhole": "keyhole:read_keyhole",
           "fk": "fk:read_fk", "fk-interactive": "fk:read_fk_interactive"}


def reader(name: str):
    """The reading function of a format, by name."""
    require(name in FORMATS, "format", f"{name!r} is not one of {sorted(FORMATS)}",
            f"pass --format {' or '.join(sorted(FORMATS))}")
    module, function = FORMATS[name].split(":")
    return getattr(importlib.import_module(f".{module}", __package__), function)


def options_of(name: str) -> set:
    """The keyword options (geometry constants, orientation) a format's reader takes."""
    params = inspect.signature(reader(name)).parameters.values()
    return {p.name for p in params if p.kind is p.KEYWORD_ONLY}


def detect(path) -> str:
    """The format of `path` where unambiguous: a folder with sub_Sig.mat is ccsocr, one with
    volume_*.npz frames consumer-nlos, one with scan_*.mat keyhole, one with meas*.mat and
    tof*.mat (or a .mat holding meas) fk, a .mat file holding rect_data is lct."""
    from .matfile import variables
    path = Path(path)
    require(path.exists(), f"dataset {path}", "does not exist", "pass the downloaded file or "
            "folder")
    if path.is_dir() and any(path.glob("volume_*.npz")):
        return "consumer-nlos"
    if path.is_dir() and any(path.glob("scan_*.mat")):
        return "keyhole"
    if path.is_dir() and any(path.glob("meas*.mat")) and any(path.glob("tof*.mat")):
        found = sorted(path.glob("meas*.mat"))  # several: `fk` says to pass one of them
        return _fk_kind(found[0]) if len(found) == 1 else "fk"
    if path.is_dir():
        require((path / "sub_Sig.mat").is_file(), f"dataset {path}", "is a folder without "
                "sub_Sig.mat, volume_*.npz, scan_*.mat or meas*.mat with tof*.mat, so its "
                "format is unknown", f"pass --format NAME ({', '.join(sorted(FORMATS))})")
        return "ccsocr"
    held = variables(path)
    if "meas" in held and "rect_data" not in held:
        return _fk_kind(path)
    require("rect_data" in held, f"dataset {path}", "holds no variable rect_data or meas, "
            "so its format is unknown", f"pass --format NAME ({', '.join(sorted(FORMATS))})")
    return "lct"


def _fk_kind(path) -> str:
    """fk for a 3-D meas (a scene), fk-interactive for a 4-D one (frames)."""
    from .matfile import variables
    shape = variables(path).get("meas", ((),))[0]
    return "fk-interactive" if len(shape) == 4 else "fk"


def read_dataset(path, format: str | None = None, **options):
    """A measured dataset as one HistogramSet (internal frame), or for a sequence format a
    (frames, metadata) pair. `format`: a name of FORMATS, or None to detect it; `options`: the
    reader's geometry constants (e.g. dt_ps, t0_ps)."""
    name = detect(path) if format is None else format
    fn = reader(name)
    extra = sorted(set(options) - options_of(name))
    require(not extra, f"{name} options", f"{extra} are not options of the {name} format "
            f"(it takes {sorted(options_of(name))})", "drop them")
    read = fn(path, **options)
    check_plausible(read, path, name)
    return read


# where each format's wall scale and bin width come from, named when a unit slip is refused
SCALE_FROM = {"ccsocr": "grid_m (--grid-m, metres per wall index)",
              "lct": "the file's `width`, or width_m (--width)",
              "fk": "calibration.mat's `width`, or width_m (--width)",
              "fk-interactive": "calibration.mat's `width`, or width_m (--width)",
              "consumer-nlos": "the frames' pt_cloud (metres)",
              "keyhole": "the scans' xpos and zpos (metres)"}
MIN_BIN_S = 1e-14  # 10 fs (3 um of path): finer than any SPAD or streak camera bins


def check_plausible(read, path, name: str) -> None:
    """Every HistogramSet a reader returns (a sequence: each frame's) spans a relay wall, not
    1000 times one, and has bins of a time-of-flight camera (1e-14 .. 5e-9 s): a length or time
    in other units is refused here, naming the dataset and the option or field that set it,
    rather than written into a capture that `locate` then blames."""
    from ...core.constants import SPEED_OF_LIGHT
    from ..ytal.checks import MAX_BIN_M, MAX_WALL_SPAN_M
    sets = [read] if hasattr(read, "time_axis") else [frame[1] for frame in read[0]]
    for key, value in ({} if sets and read is sets[0] else read[1]).items():
        try:  # a sequence's lengths beside its frames (Keyhole's stage positions, in metres)
            far = float(np.abs(np.asarray(value, dtype=np.float64)).max()) \
                if key.endswith("_m") and np.size(value) else 0.0
        except (TypeError, ValueError):
            continue
        require(far <= MAX_WALL_SPAN_M, f"dataset {path}: {key}", f"reaches {far:.4g} m, "
                f"beyond the {MAX_WALL_SPAN_M:g} m of a relay wall's scene: that looks like "
                f"millimetres (the scale comes from {SCALE_FROM[name]})", "store lengths in "
                "metres (divide millimetres by 1000)")
    for h in sets:
        pts = np.vstack([np.reshape(h.detector_spots, (-1, 3)),
                         np.reshape(h.laser_spots, (-1, 3))])
        span = float(np.ptp(pts, axis=0).max())
        require(span <= MAX_WALL_SPAN_M, f"dataset {path}: wall spots", f"span {span:.4g} m, "
                f"more than the {MAX_WALL_SPAN_M:g} m a relay wall scan covers: that looks like "
                f"millimetres or centimetres (the scale comes from {SCALE_FROM[name]})",
                "give lengths in metres (divide millimetres by 1000)")
        dt = float(h.time_axis.dt_s)
        require(MIN_BIN_S <= dt <= MAX_BIN_M / SPEED_OF_LIGHT, f"dataset {path}: bin width",
                f"is {dt:.4g} s, outside the {MIN_BIN_S:g} .. {MAX_BIN_M / SPEED_OF_LIGHT:.2g} s "
                "of a time-of-flight camera's bins: a time in other units", "pass dt_ps "
                "(--dt-ps) in picoseconds, e.g. 4")
