"""Scenes from files: a YAML (or dict) description of the setup, the targets, the time axis and
the noise, so that any case is one command (`nlos-cl simulate SCENE.yaml --out F.h5`).

Schema (SI units; every key optional unless marked; docs/scene-files.md has examples)::

    setup:
      laser_spot: [0, 0, 0]
      detector_spots: [[-0.5, 0, 0], ...]            # a list, or one generator:
        # {line: {start: [..], stop: [..], count: 3}}
        # {circle: {centre: [..], radius_m: 0.5, count: 8, start_deg: 0}}
        # {spad_patch: {centre: [..], counts: [32, 32], pitch_m: 0.0375}}
      device_distance_m: 20
      laser_spot_diameter_m / detected_spot_diameter_m / aperture_area_m2 / wall_brdf
      pulse: {fwhm_s: 70e-12, energy_j: 9.375e-9}     # or power_w + rep_rate_hz
    targets:                                          # required, at least one
      - shape: rectangle        # size_m: [width, height], normal: [nx, ny, 0] (default -x)
      - shape: box              # size_m: [sx, sy, sz]
      - shape: sphere           # radius_m
      - shape: mesh             # file: person.obj (relative to the scene file)
        # trajectory: {t_s: [0, 5], positions: [[2, 4, 0], [5, 1, 0]]}  in place of position
        # every shape: position [x, y, z] (its bounding-box centre: the truth), rotation_deg
        # [rx, ry, rz] (about x, then y, then z, around the centre), scale, brdf (Lambertian)
        # or reflectance: {model: ggx, specular: 0.5, roughness: 0.3, diffuse: 0.0}
    facet_size_m: 0.01
    occlusion: true                                   # targets shadow each other (default)
    time_axis: {dt_s: 10e-12, t0_s: .., n_bins: ..}  # default: first arrival to 18 m of path
    noise: {snr_db: 10, seed: 3}                      # or {photons: {n_pulses: 80e6, ...}, seed}
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.errors import InputError, require
from ..core.tuning import FACET_M

SETUP_KEYS = {"laser_spot", "detector_spots", "device_distance_m", "laser_spot_diameter_m",
              "detected_spot_diameter_m", "aperture_area_m2", "wall_brdf", "pulse", "finite_spots"}
SHAPES = {"rectangle": {"size_m", "normal"}, "box": {"size_m"}, "sphere": {"radius_m"},
          "mesh": {"file"}}
COMMON = {"shape", "position", "trajectory", "rotation_deg", "scale", "brdf", "reflectance"}
TOP = {"setup", "targets", "facet_size_m", "time_axis", "noise", "description", "occlusion"}


@dataclass(frozen=True)
class SceneSpec:
    """What a scene file describes: the scene, its time axis, its noise model and seed."""

    scene: object  # nlos_cl.Scene
    time_axis: object  # nlos_cl.TimeAxis
    noise: object | None  # nlos_cl.AWGN, nlos_cl.PhotonCounter or None
    seed: int
    description: str
    trajectories: tuple = ()  # per target: a nlos_cl.tracking.Trajectory, or None (static)

    @property
    def moving(self) -> bool:
        return any(t is not None for t in self.trajectories)


def _trajectory(where: str, spec):
    """`trajectory: {t_s: [...], positions: [[x, y, z], ...]}` in place of `position`."""
    if "trajectory" not in spec:
        return None
    from ..physics.trajectory import Trajectory
    require("position" not in spec, f"{where}.trajectory", "given together with position",
            "give one: position (a static target) or trajectory (a moving one)")
    raw = _keys(f"{where}.trajectory", spec["trajectory"], {"t_s", "positions"})
    try:
        return Trajectory(raw.get("t_s"), raw.get("positions"))
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


def _keys(where: str, mapping, allowed: set) -> dict:
    require(isinstance(mapping, dict), where, f"expected a mapping, got {type(mapping).__name__}",
            "write it as `key: value` lines (YAML)")
    unknown = sorted(set(mapping) - allowed)
    require(not unknown, f"{where}.{unknown[0]}" if unknown else where,
            "is not a known key", f"use one of {sorted(allowed)}")
    return mapping


def _vector(where: str, value, n=3) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        arr = np.zeros(0)
    require(arr.shape == (n,) and bool(np.all(np.isfinite(arr))), where,
            f"expected {n} finite numbers, got {value!r}", f"write e.g. {[0.0] * n}")
    return arr


def _number(where: str, value, *, positive=True) -> float:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    require(ok and (value > 0 or not positive), where, f"expected a "
            f"{'positive ' if positive else ''}number, got {value!r}", "write e.g. 0.01")
    return float(value)


def _spots(value):
    from ..physics import layouts
    if isinstance(value, dict):
        require(len(value) == 1 and next(iter(value)) in ("line", "circle", "spad_patch"),
                "setup.detector_spots", f"a generator must be one of line, circle, spad_patch, "
                f"got {sorted(value)}", "write e.g. {circle: {centre: [-1, 0, 0], radius_m: 0.5,"
                " count: 8}}")
        (kind, params), = value.items()
        params = _keys(f"setup.detector_spots.{kind}", params,
                       {"line": {"start", "stop", "count"},
                        "circle": {"centre", "radius_m", "count", "start_deg"},
                        "spad_patch": {"centre", "counts", "pitch_m"}}[kind])
        return getattr(layouts, kind)(**params)
    return value


def _setup(raw: dict):
    from ..physics.scene import Pulse, Setup
    raw = dict(_keys("setup", raw or {}, SETUP_KEYS))
    if "detector_spots" in raw:
        raw["detector_spots"] = _spots(raw["detector_spots"])
    if "pulse" in raw:
        pulse = _keys("setup.pulse", raw["pulse"], {"fwhm_s", "energy_j", "power_w",
                                                    "rep_rate_hz"})
        if "power_w" in pulse or "rep_rate_hz" in pulse:
            raw["pulse"] = Pulse.from_laser(pulse.get("power_w", 0.75),
                                            pulse.get("rep_rate_hz", 80e6),
                                            pulse.get("fwhm_s", 70e-12))
        else:
            raw["pulse"] = Pulse(**pulse)
    return Setup(**raw)


def _rotation(where: str, degrees) -> np.ndarray:
    rx, ry, rz = np.radians(_vector(where, degrees))
    cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
    x = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    z = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return z @ y @ x  # about x first, then y, then z


def _mesh(where: str, spec: dict, base: Path, cell: float):
    from ..physics import meshes
    shape = spec.get("shape")
    require(shape in SHAPES, f"{where}.shape", f"unknown shape {shape!r}",
            f"use one of {sorted(SHAPES)}")
    _keys(where, spec, COMMON | SHAPES[shape])
    if shape == "rectangle":
        w, h = _vector(f"{where}.size_m", spec.get("size_m", [0.3, 1.6]), 2)
        normal = _vector(f"{where}.normal", spec.get("normal", [-1, 0, 0]))
        return meshes.rectangle(w, h, centre=(0, 1, 0), normal=normal, cell_m=cell)
    if shape == "box":
        return meshes.box(_vector(f"{where}.size_m", spec.get("size_m", [0.3, 0.3, 1.6])),
                          centre=(0, 1, 0), cell_m=cell)
    if shape == "sphere":
        return meshes.sphere(_number(f"{where}.radius_m", spec.get("radius_m", 0.2)),
                             centre=(0, 1, 0), facet_size_m=cell)
    require(isinstance(spec.get("file"), str), f"{where}.file", "is missing or not a path",
            "write the mesh file's path (relative to the scene file)")
    return meshes.load_mesh(base / spec["file"])


def _target(i: int, spec, base: Path, cell: float):
    """(Target, Trajectory or None): the mesh scaled and rotated about its centre, then its
    bounding-box centre moved to `position` (or to where its trajectory starts)."""
    from ..physics.scene import Target
    where = f"targets[{i}]"
    require(isinstance(spec, dict), where, f"expected a mapping, got {spec!r}",
            "write e.g. {shape: sphere, radius_m: 0.3, position: [2, 4, 0]}")
    mesh = _mesh(where, spec, base, cell)
    centre = mesh.bounds.mean(axis=0)
    vertices = (mesh.vertices - centre) * _number(f"{where}.scale", spec.get("scale", 1.0))
    if "rotation_deg" in spec:
        vertices = vertices @ _rotation(f"{where}.rotation_deg", spec["rotation_deg"]).T
    path = _trajectory(where, spec)
    start = path.at(0.0) if path is not None else spec.get("position", [4, 2, 0])
    mesh.vertices = vertices + _vector(f"{where}.position", start)
    try:
        brdf = spec.get("brdf", 0.1284)
        if "reflectance" in spec:  # {model: ggx, specular: .., roughness: .., diffuse: ..}
            from ..physics.reflectance import from_spec
            require("brdf" not in spec, f"{where}.reflectance", "given together with brdf",
                    "give one: brdf (a Lambertian number) or reflectance (a model)")
            brdf = from_spec(spec["reflectance"])
        return Target(mesh, brdf=brdf), path
    except InputError as exc:  # say which target
        raise InputError(f"{where}: {exc}") from None


def _time_axis(raw, setup):
    from ..core.paths import TimeAxis, default_time_axis
    raw = _keys("time_axis", raw or {}, {"dt_s", "t0_s", "n_bins", "max_hidden_path_m"})
    dt = _number("time_axis.dt_s", raw.get("dt_s", 10e-12))
    if "t0_s" in raw or "n_bins" in raw:
        require("t0_s" in raw and "n_bins" in raw, "time_axis", "t0_s and n_bins go together",
                "give both, or neither (then the window is derived)")
        return TimeAxis(raw["t0_s"], dt, raw["n_bins"])
    return default_time_axis(setup, dt, _number("time_axis.max_hidden_path_m",
                                                raw.get("max_hidden_path_m", 18.0)))


def _noise(raw):
    """(noise model or None, seed)."""
    from ..physics.noise import AWGN, PhotonCounter, check_seed
    if raw is None:
        return None, 0
    raw = _keys("noise", raw, {"snr_db", "photons", "seed"})
    seed = check_seed(raw.get("seed", 0))
    require(not ("snr_db" in raw and "photons" in raw), "noise", "has both snr_db and photons",
            "pick one noise model")
    if "photons" in raw:
        params = _keys("noise.photons", raw["photons"] or {}, set(PhotonCounter.__dataclass_fields__))
        return PhotonCounter(**params), seed
    if "snr_db" in raw:
        return AWGN(raw["snr_db"]), seed
    return None, seed


def load_scene(source) -> SceneSpec:
    """A SceneSpec from a YAML file path or an already-parsed dict."""
    from ..physics.scene import Scene
    base = Path(".")
    if not isinstance(source, dict):
        base, raw = Path(source).parent, read_yaml(Path(source))
    else:
        raw = source
    raw = _keys("scene", raw, TOP)
    setup = _setup(raw.get("setup"))
    cell = _number("facet_size_m", raw.get("facet_size_m", FACET_M))
    targets = raw.get("targets")
    require(isinstance(targets, list) and len(targets) >= 1, "targets", "needs at least one "
            "target", "add e.g. `targets: [{shape: rectangle, position: [4, 2, 0]}]`")
    placed, paths = zip(*[_target(i, t, base, cell) for i, t in enumerate(targets)])
    occlusion = raw.get("occlusion", True)
    require(isinstance(occlusion, bool), "occlusion", f"must be true or false, got {occlusion!r}",
            "write occlusion: true (the default) or false")
    scene = Scene(setup, placed[0], cell, more_targets=tuple(placed[1:]), occlusion=occlusion)
    noise, seed = _noise(raw.get("noise"))
    return SceneSpec(scene, _time_axis(raw.get("time_axis"), setup), noise, seed,
                     str(raw.get("description", "")), tuple(paths))


def yaml_loader():
    """PyYAML's SafeLoader, but `1e-11` is a number (YAML 1.2) rather than the text '1e-11'
    (YAML 1.1 wants a dot in the mantissa: `10e-12` would silently be a string)."""
    import re

    import yaml

    class Loader(yaml.SafeLoader):
        pass
    Loader.add_implicit_resolver("tag:yaml.org,2002:float", re.compile(
        r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"), list("-+0123456789."))
    return Loader


def read_yaml(path: Path, what: str = "scene file") -> dict:
    """A short YAML file (scene, study) as a mapping, with clear errors."""
    import yaml
    path = Path(path)
    require(path.is_file(), f"{what} {path}", "does not exist", "pass a .yaml file")
    require(path.stat().st_size < 1 << 20, f"{what} {path}", "is larger than 1 MiB",
            "it is a short description; meshes go in their own files")
    try:
        raw = yaml.load(path.read_text(encoding="utf-8"), Loader=yaml_loader())
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise InputError(f"{what} {path}: is not valid YAML ({str(exc).splitlines()[0]}). "
                         "Fix: check the indentation and brackets near that line") from None
    require(isinstance(raw, dict), f"{what} {path}", "is not a mapping of keys",
            "write `key: value` lines (docs/scene-files.md, docs/sweeps.md)")
    return raw
