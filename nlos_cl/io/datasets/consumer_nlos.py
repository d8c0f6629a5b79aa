"""A consumer multizone ToF sensor's frames as the consumer-nlos authors publish them
(Somasundaram, Young, Dave, Pediredla, Raskar, "Imaging Hidden Objects with Consumer LiDAR via
Motion Induced Sampling", arXiv 2605.17865; github.com/sidsoma/consumer-nlos,
captured_data/<capture>/volume_%06d.npz): a folder of one .npz file per frame.

Facts, from the upstream code (as summarised in ../shared/realdata/consumer-nlos/README.md):
- an ST VL53L8: 16 zones, `hists` (16, 128) one histogram per zone, processed floats (not
  integer counts), bins of 250 ps (`t_res` in configs/tracking.yaml);
- t = 0 when light leaves the wall towards the hidden scene (the first bounce is cropped
  upstream, data/dataloader.py): ours is t0 = 0, bin k starting at k x 250 ps;
- the upstream model is confocal, path = 2 |p - wall spot| (train/canon.py): each zone is its own
  laser point and detection point. The sensor floods the wall, so this is an approximation;
- `pt_cloud` (16, 3): the wall spot each zone sees, metres, the wall close to the plane z = 0
  and the hidden space z > 0 in their frame;
- `particles` (1000, 3): the authors' particle filter's state for the frame: their ESTIMATE of
  the person's position, not a ground truth. Its mean is kept per frame as metadata
  (`reference_positions`, their frame), never as the sequence's `frame_truths`;
- about 14 Hz capture (the upstream video writer's fps): frame k (the number in its file name)
  is at t = k / fps.

Their frame to ours: the particle means move a metre in x and half a metre in z but stay within
~0.1 m in y (README), so their y is the vertical axis. Ours (x, y, z) = (-X, Z, Y) of theirs
(X, Y, Z): the proper rotation (determinant +1) that y-tal's own frame uses
(nlos_cl.io.ytal.frames.YTAL), so a written sequence's (X, Y, Z) are the authors' coordinates
and `nlos-cl track` reports positions directly comparable with their particles. Whether their y
points up or down is not documented; the ellipse model does not depend on it.

Their wall spots lie up to 1.2 cm off z = 0 (a plane fit's scatter: their mean z is 0), beyond
y-tal's 1 cm wall tolerance (frames.WALL_TOLERANCE_M); we put them on the plane (our y = 0). A
spot dz off the wall changes a confocal path by at most 2 dz = 2.4 cm, a third of one 250 ps bin
(7.5 cm of path). The largest offset is reported as metadata `wall_offset_max_m`.
"""
from __future__ import annotations

import re
import zipfile
from pathlib import Path

import numpy as np

from ...core.constants import SPEED_OF_LIGHT
from ...core.errors import InputError, require
from ...core.histograms import HistogramSet
from ...core.limits import MAX_FRAMES, require_count, require_memory
from ...core.paths import PathCalibration, TimeAxis

BIN_PS = 250.0  # configs/tracking.yaml: t_res 250e-12
FPS = 14.0  # the upstream video writer's fps (README): the capture rate
PATTERN = re.compile(r"volume_(\d+)\.npz")
FIELDS = ("hists", "pt_cloud")  # every frame has these
OPTIONAL = ("particles", "cam_z")  # the person-tracking capture's particles; the moving
# camera's height in cam_localization.py's capture (upstream data/dataloader.py, cam_track)
# theirs (X, Y, Z) -> ours (x, y, z) = (-X, Z, Y): rows are our axes in terms of theirs
TO_INTERNAL = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])


def frame_files(folder) -> list[tuple[int, Path]]:
    """(k, path) of every volume_<k>.npz in `folder`, in frame order. Every entry so named must
    be a regular file, each frame number once: a frame that cannot be read is refused by
    name, never skipped (its absence would go unseen in the sequence)."""
    from ...core.gate import regular_size
    folder = Path(folder)
    require(folder.is_dir(), f"dataset {folder}", "is not a folder", "pass the folder that "
            "holds volume_000000.npz, volume_000001.npz, ...")
    found, seen = [], {}
    for p in folder.iterdir():
        m = PATTERN.fullmatch(p.name)
        if not m:
            continue
        regular_size(p, f"dataset {folder}: frame {p.name}", "remove it, or put the frame's "
                     "own .npz file there")
        k = int(m.group(1))
        require(k not in seen, f"dataset {folder}: frame {p.name}", f"is frame {k}, as "
                f"{seen.get(k)} is", "keep one file per frame number")
        seen[k] = p.name
        found.append((k, p))
        require_count(f"dataset {folder}", len(found), MAX_FRAMES, "frames", "convert a "
                      "folder holding fewer frames")
    require(len(found) > 0, f"dataset {folder}", "holds no volume_*.npz frame", "pass the "
            "capture folder (e.g. captured_data/st_spad_person_tracking)")
    return sorted(found)


def read_consumer_nlos(folder, *, dt_ps: float = BIN_PS, t0_ps: float = 0.0, fps: float = FPS,
                       static: bool = False):
    """A consumer-nlos capture folder as (frames, metadata): frames a list of (t_s,
    HistogramSet) pairs (confocal: laser spots = detector spots, one per zone; write_sequence
    takes them as they are), metadata {"fps", "reference_positions" (F, 3) the authors'
    particle means in their frame where the files hold particles, "reference": what they are,
    "cam_z" where they hold it, ...}. dt_ps: bin width; t0_ps: bin 0's start after light
    leaves the wall; fps: frames per second (frame k at k / fps).
    static: every frame's zones pooled into ONE confocal HistogramSet (F x 16 histograms, each
    at its own frame's wall spot), for a scene that does not move while the sensor does (the
    motion-induced aperture the paper is named after); a sequence needs one wall layout, so
    frames whose pt_cloud differs are refused without it. Zones of several frames on one wall
    spot are summed into one histogram (`_pooled`)."""
    for name, value, default in (("dt_ps", dt_ps, BIN_PS), ("fps", fps, FPS)):
        require(np.isfinite(value) and value > 0, name, f"must be positive, got {value}",
                f"pass e.g. {default:g}")
    require(np.isfinite(t0_ps), "t0_ps", f"must be finite, got {t0_ps}", "pass e.g. 0")
    files = frame_files(folder)
    first = _declared(files[0][1])
    n_zones, n_t = first["hists"][0]
    per_frame = sum(8.0 * np.prod(shape) for shape, _, _ in first.values())
    require_memory(f"dataset {folder}", 2.0 * per_frame * len(files), f"reading {len(files)} "
                   "frames", "convert a folder holding fewer frames")
    spots0 = _load(files[0][1], n_zones, n_t)["pt_cloud"]
    axis = TimeAxis(t0_ps * 1e-12, dt_ps * 1e-12, n_t)
    frames, walls, means, cam_z, offset = [], [], [], [], 0.0
    for k, path in files:
        got = _load(path, n_zones, n_t)
        require(static or np.array_equal(got["pt_cloud"], spots0), f"{path}: pt_cloud",
                "differs from the first frame's (the sensor moved), but a sequence holds one "
                "wall layout", "pass --static to pool every frame into one capture of a scene "
                "that does not move, or convert the frames of one sensor pose together")
        wall, moved = _wall_spots(got["pt_cloud"], path)
        offset = max(offset, moved)
        walls.append(wall)
        frames.append((k / fps, HistogramSet(got["hists"], axis, wall, wall,
                                             PathCalibration(SPEED_OF_LIGHT, [0.0]))))
        if "particles" in got:
            means.append(got["particles"].mean(axis=0))
        if "cam_z" in got:
            cam_z.append(got["cam_z"].ravel().tolist())
    if static:
        return _pooled(np.concatenate([h.data for _, h in frames]), np.concatenate(walls), axis)
    meta = {"fps": float(fps), "frame_numbers": [k for k, _ in files],
            "wall_offset_max_m": offset}
    if len(means) == len(files):
        meta.update(reference_positions=np.asarray(means).tolist(),
                    reference="the authors' particle-filter mean per frame (their estimate, "
                              "not ground truth), in the file's (X, Y, Z)")
    if len(cam_z) == len(files):
        meta["cam_z"] = cam_z
    return frames, meta


def _pooled(data, spots, axis) -> HistogramSet:
    """One confocal HistogramSet of every frame's zones; zones of different frames on one wall
    spot (within SAME_SPOT_M: the capture reader's test) summed into one histogram at their
    mean spot, since the same spot measured twice is one measurement, longer."""
    from ..ytal.frames import SAME_SPOT_M
    _, group = np.unique(np.round(spots / SAME_SPOT_M), axis=0, return_inverse=True)
    group = group.ravel()
    n = int(group.max()) + 1
    summed = np.zeros((n, data.shape[1]))
    np.add.at(summed, group, data)
    centre = np.zeros((n, 3))
    np.add.at(centre, group, spots)
    centre /= np.bincount(group, minlength=n)[:, None]
    return HistogramSet(summed, axis, centre, centre, PathCalibration(SPEED_OF_LIGHT, [0.0]))


def _members(z, path) -> dict[str, str]:
    """field -> the zip member that holds it, by its real name: `hists.npy` (as np.savez
    writes) or a bare `hists`; a field named twice (both, or one name twice) is refused, so
    the member whose header is checked is the member read."""
    names = [i.filename for i in z.infolist()]
    out = {}
    for field in FIELDS + OPTIONAL:
        held = [n for n in names if n in (field, field + ".npy")]
        require(len(held) <= 1, f"{path}: {field}", f"is held by {len(held)} members "
                f"({', '.join(held)})", "pass the dataset's own, unmodified file")
        if held:
            out[field] = held[0]
    return out


def _declared(path) -> dict:
    """{field: (shape, dtype, member)} as the .npz's members declare them (their .npy headers),
    read without loading any array, so sizes are checked before reading."""
    from ...core.gate import open_regular
    try:
        with open_regular(path, f"{path}", "pass the dataset's own volume_*.npz file") as fh, \
                zipfile.ZipFile(fh) as z:
            members = _members(z, path)
            out = {name: _header(z, member, path) + (member,)
                   for name, member in members.items()}
            held = sorted(i.filename for i in z.infolist())[:10]
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - BadZipFile, encryption, bad npy: all damage
        require(False, f"{path}", f"is not a readable .npz file ({type(exc).__name__}: "
                f"{str(exc)[:120]})", "download the file again")
    missing = [f for f in FIELDS if f not in out]
    require(not missing, f"{path}", f"lacks {missing} (it holds {held})",
            "pass the dataset's own, unmodified volume_*.npz files")
    for name, (shape, dtype, _) in out.items():
        small = name == "cam_z" and int(np.prod(shape)) <= 3  # a height: any small shape
        require((len(shape) == 2 or small) and dtype.kind in "fiu", f"{path}: {name}",
                f"is declared {dtype} {shape}, expected a numeric 2-D array", "pass the "
                "dataset's own file")
    return out


def _header(z, member, path) -> tuple:
    """(shape, dtype) from a .npy member's header (numpy.lib.format), no data read; a member
    that is no .npy array (a raw file under a field's name) is refused."""
    with z.open(member) as fh:
        require(fh.read(6) == b"\x93NUMPY", f"{path}: {member}", "is not a .npy array",
                "pass the dataset's own, unmodified file")
        fh.seek(0)
        version = np.lib.format.read_magic(fh)
        read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                else np.lib.format.read_array_header_2_0)
        shape, _, dtype = read(fh)
    return tuple(shape), dtype


def _load(path, n_zones, n_t):
    """One frame's {hists (Z, T), pt_cloud (Z, 3), and where present particles (P, 3) and
    cam_z} as float64, their declared shapes checked against the first frame's before
    reading, each read from the very member whose header was checked."""
    declared = _declared(path)
    for name, want in (("hists", (n_zones, n_t)), ("pt_cloud", (n_zones, 3))):
        require(declared[name][0] == want, f"{path}: {name}", f"has shape "
                f"{declared[name][0]}, expected {want} (as the first frame's hists)",
                "convert the frames of one capture together")
    require("particles" not in declared or declared["particles"][0][1:] == (3,),
            f"{path}: particles", f"has shape {declared.get('particles', ((),))[0]}, "
            "expected (P, 3)", "pass the dataset's own file")
    require_memory(f"{path}", 16.0 * sum(np.prod(s) for s, _, _ in declared.values()),
                   "reading one frame", "pass the dataset's own files")
    try:
        with zipfile.ZipFile(path) as z:
            out = {}
            for name, (_, _, member) in declared.items():
                with z.open(member) as fh:
                    value = np.lib.format.read_array(fh, allow_pickle=False)
                out[name] = np.asarray(value, dtype=np.float64)
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - BadZipFile, encryption, bad npy: all damage
        require(False, f"{path}", f"cannot be read, the file is damaged "
                f"({type(exc).__name__}: {str(exc)[:120]})", "download the file again")
    for name, value in out.items():
        require(bool(np.all(np.isfinite(value))), f"{path}: {name}", "contains NaN or inf",
                "pass the dataset's own, unmodified file")
    return out


def _wall_spots(pt_cloud, path) -> tuple[np.ndarray, float]:
    """Their wall spots in our frame, put on the wall plane y = 0 (module docstring), and the
    largest distance moved."""
    spots = np.asarray(pt_cloud) @ TO_INTERNAL.T
    offset = float(np.abs(spots[:, 1]).max())
    require(offset <= 0.05, f"{path}: pt_cloud", f"lies up to {offset:.3g} m off the wall plane "
            "z = 0", "pass the dataset's own files (their wall is within 1.2 cm of z = 0)")
    spots[:, 1] = 0.0
    return spots, offset
