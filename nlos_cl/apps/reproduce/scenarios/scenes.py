"""A scenario draw (draws: plain data) as the files a user would have: a scene file (YAML, as
docs/scene-files.md describes, a person as an OBJ mesh beside it) for `nlos-cl simulate`; and
what the scoring needs from the geometry: each truth in the capture file's frame, the share of
each truth's light no other object shadows, and the hidden path its returns span (for gated and
short records). A tilted or moved wall is the written capture rewritten by a rigid transform of
every point it stores (`move`); a bumpy wall is simulated where its jittered points lie
(`simulate_bumpy`: the scene file keeps wall spots on y = 0, so this is the library's simulate
and write_capture, as `nlos-cl simulate` calls them)."""
from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np

from ....core.constants import SPEED_OF_LIGHT
from ....io.ytal.frames import YTAL
from . import sequences

FILE_POINTS = ("sensor_grid_xyz", "laser_grid_xyz", "sensor_xyz", "laser_xyz")
FILE_NORMALS = ("sensor_grid_normals", "laser_grid_normals")
TRUTHS = ("target", "occluder")  # the roles that are truths (furniture is clutter)


def _person(o: dict, path: Path) -> None:
    """An upright capsule of the person's radius and overall height, as an OBJ file."""
    import trimesh
    r, h = o["radius_m"], o["height_m"]
    trimesh.creation.capsule(height=max(h - 2 * r, 1e-3), radius=r, count=[24, 12]).export(
        path, file_type="obj")


def target_spec(o: dict, i: int, folder: Path, span_s: float) -> dict:
    """One object as a scene file's `targets` entry (a person's mesh written beside it)."""
    if o["shape"] == "plate":
        spec = {"shape": "rectangle", "size_m": o["size"], "normal": o["normal"]}
    elif o["shape"] in ("box", "cabinet"):
        spec = {"shape": "box", "size_m": o["size"], "rotation_deg": [0, 0, o["yaw_deg"]]}
    else:
        name = f"person-{i}.obj"
        _person(o, folder / name)
        spec = {"shape": "mesh", "file": name}
    if o.get("path"):
        spec["trajectory"] = {"t_s": [0.0, span_s], "positions": o["path"]}
    else:
        spec["position"] = o["centre"]
    return spec


def span_of(d: dict) -> float:
    q = d.get("sequence") or {}
    return (q["frames"] - 1) / q["fps"] if q else 0.0


def scene_dict(d: dict, cfg: dict, folder: Path, time_axis: dict | None = None) -> dict:
    objs = ordered(d)
    out = {"description": f"scenario {d['index']} ({d['family']}), master seed "
                          f"{d['master_seed']}",
           "setup": {"detector_spots": d["layout"]["spots"]},
           "targets": [target_spec(o, i, folder, span_of(d)) for i, o in enumerate(objs)],
           "facet_size_m": cfg["facet_size_m"], "noise": d["noise"]}
    if time_axis:
        out["time_axis"] = time_axis
    return out


def ordered(d: dict) -> list:
    """The objects as the scene file lists them: the truths first (the file's truths are the
    scene's targets in order; a sequence's are its movers), then furniture."""
    return [o for o in d["objects"] if o["role"] in TRUTHS] + \
        [o for o in d["objects"] if o["role"] not in TRUTHS]


def write(d: dict, cfg: dict, folder: Path) -> Path:
    """The draw's scene file, folder/scene.yaml (a record's window from its geometry)."""
    from ....io.yamlfile import dump_json_yaml
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "scene.yaml"
    path.write_text(dump_json_yaml(scene_dict(d, cfg, folder)), "utf-8")
    if d.get("record"):
        window = record_axis(d["record"], load(path))
        path.write_text(dump_json_yaml(scene_dict(d, cfg, folder, window)), "utf-8")
    return path


def load(path: Path):
    from ....io.scenefile import load_scene
    return load_scene(path)


def path_span(scene) -> tuple[float, float]:
    """The shortest and longest hidden path (laser spot -> facet -> detector spot) over every
    target's facets and every spot: where its returns begin and end."""
    lo, hi = math.inf, 0.0
    spots = np.asarray(scene.setup.detector_spots)
    for i in range(len(scene.targets)):
        c = scene.facets(i).centres
        r1 = np.linalg.norm(c - scene.setup.laser_spot, axis=1)[:, None]
        p = r1 + np.linalg.norm(c[:, None] - spots[None], axis=2)
        lo, hi = min(lo, float(p.min())), max(hi, float(p.max()))
    return lo, hi


def record_axis(record: dict, spec) -> dict:
    """The scene file's time_axis of a gated record (opening open_before_m of hidden path
    before the first return) or a short one (from the first possible arrival), each closing
    after_m past the last return."""
    axis = spec.time_axis
    lo, hi = path_span(spec.scene)
    start = max(lo - record.get("open_before_m", 0.0), 0.0) if record["kind"] == "gated" else 0.0
    n = math.ceil((hi + record["after_m"] - start) / (SPEED_OF_LIGHT * axis.dt_s))
    return {"t0_s": axis.t0_s + start / SPEED_OF_LIGHT, "dt_s": axis.dt_s, "n_bins": n}


def to_file(points, wall: dict | None) -> np.ndarray:
    """Scene points (nlos_cl's frame) as the capture file states them: y-tal's frame, moved by
    the wall's rigid transform where it has one."""
    p = YTAL.from_internal(np.asarray(points, float).reshape(-1, 3))
    if wall and wall["kind"] != "bumpy":
        p = p @ np.asarray(wall["rotation"]).T + np.asarray(wall["move_m"])
    return p


def lit_shares(scene) -> list[float]:
    """Per target of the scene: the area-weighted share of its (facet, detector spot) pairs
    that see both spots past every object, of those that face both (its light alone)."""
    out = []
    laser, spots = scene.setup.laser_spot, np.asarray(scene.setup.detector_spots)
    for i in range(len(scene.targets)):
        f = scene.facets(i)
        faces = ((f.normals * (laser - f.centres)).sum(1) > 0)[None] & (
            np.einsum("fk,dfk->df", f.normals, spots[:, None] - f.centres[None]) > 0)
        seen = scene.visibility(i)
        seen = faces if seen is None else seen & faces
        total = float((faces * f.areas).sum())
        out.append(float((seen * f.areas).sum()) / total if total > 0 else 0.0)
    return out


def frame_scene(d: dict, cfg: dict, folder: Path, t_s: float):
    """A sequence's scene at time t_s (every mover where it is then), for its shadows."""
    from ....io.scenefile import load_scene
    placed = {**d, "objects": [{**{k: v for k, v in o.items() if k != "path"},
                                "centre": sequences.at(o, t_s, span_of(d)).tolist()}
                               for o in d["objects"]]}
    raw = scene_dict(placed, cfg, folder)
    for t in raw["targets"]:  # the person files written beside scene.yaml
        if "file" in t:
            t["file"] = str(folder / t["file"])
    return load_scene(raw).scene


def move(path: Path, wall: dict) -> None:
    """Rewrite capture `path` in place with every point it stores moved by x -> R x + t (its
    y-tal frame): wall points and devices, normals rotated, and the truths nlos_cl keeps in its
    metadata (YTAL's internal frame), as tests/io/test_wall_frames.py's `move`."""
    import h5py

    from ....io.yamlfile import dump_json_yaml
    R, t = np.asarray(wall["rotation"]), np.asarray(wall["move_m"])

    def moved(q):
        return YTAL.to_internal(YTAL.from_internal(np.asarray(q, float)) @ R.T + t).tolist()
    with h5py.File(path, "a") as f:
        for key in FILE_POINTS + FILE_NORMALS:
            if key in f:
                p = f[key][()].astype(np.float64)
                q = p.reshape(-1, 3) @ R.T + (0 if key in FILE_NORMALS else t)
                f[key][()] = q.reshape(p.shape).astype(p.dtype)
        info = json.loads(f["scene_info"][()])
        ours = info["nlos_cl"]
        ours["truth"] = moved(ours["truth"])
        ours["truths"] = [moved(q) for q in ours["truths"]]
        del f["scene_info"]
        f["scene_info"] = dump_json_yaml(info)


def simulate_bumpy(scene_path: Path, bumps, out: Path) -> None:
    """The scene file simulated with its laser spot and detector spots moved off the wall
    plane by `bumps` (m, laser first), written as `nlos-cl simulate` writes a capture."""
    import nlos_cl as nl
    spec = load(scene_path)
    setup = spec.scene.setup
    # Setup keeps its spots on y = 0; the forward model takes any point (test_wall_frames)
    spots = np.array(setup.detector_spots)
    spots[:, 1] = bumps[1:]
    object.__setattr__(setup, "detector_spots", spots)
    object.__setattr__(setup, "laser_spot", np.array([0.0, bumps[0], 0.0]) + setup.laser_spot)
    hist = nl.add_noise(nl.simulate(spec.scene, spec.time_axis), model=spec.noise,
                        seed=spec.seed).histograms()
    truths = [[float(v) for v in p] for p in spec.scene.truths]
    nl.write_capture(out, hist, device_distance_m=setup.device_distance_m,
                     metadata={"scene": spec.description, "targets": truths,
                               "noise": repr(spec.noise), "seed": spec.seed})


def copy_scene(folder: Path, dest: Path) -> None:
    """Keep a draw's scene file and meshes (for a failure worth a look)."""
    dest.mkdir(parents=True, exist_ok=True)
    for p in folder.iterdir():
        if p.suffix in (".yaml", ".obj"):
            shutil.copy(p, dest / p.name)
