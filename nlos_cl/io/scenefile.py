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

from ..core.errors import InputError, require, shown
from ..core.tuning import FACET_M
from .yamlfile import is_number, whole_number

SETUP_KEYS = {"laser_spot", "detector_spots", "device_distance_m", "laser_spot_diameter_m",
              "detected_spot_diameter_m", "aperture_area_m2", "wall_brdf", "pulse", "finite_spots"}
SHAPES = {"rectangle": {"size_m", "normal"}, "box": {"size_m"}, "sphere": {"radius_m"},
          "mesh": {"file"}}
COMMON = {"shape", "position", "trajectory", "rotation_deg", "scale", "brdf", "reflectance"}
TOP = {"setup", "targets", "facet_size_m", "time_axis", "noise", "description", "occlusion"}
# Plausible bounds (SI units): beyond them a value is a unit slip (millimetres for metres,
# picoseconds written as seconds) or a typo, and the physics would under- or overflow quietly
# (a device 1e39 m away returns no light; a pulse 1e30 s wide is no pulse) instead of saying so.
MAX_SCENE_M = 100.0  # wall spots and hidden targets lie within 100 m of the origin
MAX_SPOTS = 1 << 16  # detector spots a generator may make (a 256 x 256 SPAD array)
RANGES = {  # field: (low, high, example); low is exclusive unless it is 0 for a rate or jitter
    "setup.device_distance_m": (0, 1e4, 20), "setup.laser_spot_diameter_m": (0, 10, 0.07),
    "setup.detected_spot_diameter_m": (0, 10, 0.1), "setup.aperture_area_m2": (0, 100, 5e-4),
    "setup.wall_brdf": (0, 1 / math.pi, 0.2579),  # Lambertian: albedo / pi <= 1 / pi
    "setup.pulse.fwhm_s": (0, 1e-7, 70e-12), "setup.pulse.energy_j": (0, 1.0, 9.375e-9),
    "setup.pulse.power_w": (0, 1e4, 0.75), "setup.pulse.rep_rate_hz": (0, 1e10, 80e6),
    "noise.snr_db": (-100, 200, 10), "noise.photons.n_pulses": (0, 1e15, 80e6),
    "noise.photons.efficiency": (0, 1, 0.8), "noise.photons.dark_count_rate_hz": (0, 1e9, 100),
    "noise.photons.ambient_rate_hz": (0, 1e12, 1e4), "noise.photons.jitter_s": (0, 1e-7, 30e-12),
    "noise.photons.tdc_bin_s": (0, 1e-7, 50e-12), "noise.photons.wavelength_m": (0, 1e-4, 1.53e-6),
    "time_axis.dt_s": (0, 1e-7, 10e-12), "time_axis.t0_s": (-1e-3, 1e-3, 1.3e-7),
    "time_axis.max_hidden_path_m": (0, 1e3, 18), "facet_size_m": (0, 1, 0.01),
    "radius_m": (0, MAX_SCENE_M, 0.2), "scale": (0, 1e3, 1), "circle.radius_m": (0, 10, 0.5),
    "spad_patch.pitch_m": (0, 10, 0.0375), "start_deg": (-3600, 3600, 0),
}
CLOSED_LOW = {"noise.snr_db", "time_axis.t0_s", "start_deg", "noise.photons.dark_count_rate_hz",
              "noise.photons.ambient_rate_hz", "noise.photons.jitter_s"}


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
    t_s, positions = raw.get("t_s"), raw.get("positions")
    require(isinstance(t_s, list) and all(is_number(t) for t in t_s), f"{where}.trajectory.t_s",
            f"expected a list of times in seconds, got {shown(t_s)}", "write e.g. t_s: [0, 5]")
    require(isinstance(positions, list), f"{where}.trajectory.positions", f"expected a list "
            f"of [x, y, z], got {shown(positions)}", "write e.g. positions: [[2, 4, 0], [5, 1, 0]]")
    positions = [_point(f"{where}.trajectory.positions[{i}]", p) for i, p in enumerate(positions)]
    try:
        return Trajectory(t_s, positions)
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
    ok = isinstance(value, (list, tuple, np.ndarray)) and len(value) == n and \
        all(is_number(v) for v in value)
    require(ok, where, f"expected {n} finite numbers, got {shown(value)}", f"write e.g. {[0.0] * n}")
    return np.asarray(value, dtype=np.float64)


def _point(where: str, value) -> np.ndarray:
    """A position (m): within MAX_SCENE_M of the origin, or it is likely millimetres."""
    p = _vector(where, value)
    far = float(np.abs(p).max())
    require(far <= MAX_SCENE_M, where, f"{shown(value)} lies {far:.4g} m from the origin, "
            f"beyond the {MAX_SCENE_M:g} m a scene spans: that looks like millimetres",
            f"write metres ({[round(float(v) / 1000, 6) for v in p]} if it was mm)")
    return p


def _number(where: str, value, field: str | None = None) -> float:
    """A number in RANGES[field] (default: the last part of `where`)."""
    key = field or next(k for k in (where, where.rsplit(".", 1)[-1]) if k in RANGES)
    low, high, example = RANGES[key]
    closed = key in CLOSED_LOW
    ok = is_number(value) and (value >= low if closed else value > low) and value <= high
    unit = next((u for end, u in UNITS if key.endswith(end)), "")
    require(ok, where, f"expected a number{unit} in {'[' if closed else '('}{low:g}, {high:g}], "
            f"got {shown(value)}", f"write e.g. {example:g}")
    return float(value)


UNITS = (("_m2", " (square metres)"), ("_m", " (metres)"), ("_s", " (seconds)"),
         ("_j", " (joules)"), ("_w", " (watts)"), ("_hz", " (hertz)"), ("_db", " (decibels)"),
         ("_deg", " (degrees)"))


def _spots(value):
    from ..physics import layouts
    if isinstance(value, dict):
        require(len(value) == 1 and next(iter(value)) in ("line", "circle", "spad_patch"),
                "setup.detector_spots", f"a generator must be one of line, circle, spad_patch, "
                f"got {shown(sorted(value))}",
                "write e.g. {circle: {centre: [-1, 0, 0], radius_m: 0.5, count: 8}}")
        (kind, params), = value.items()
        where = f"setup.detector_spots.{kind}"
        params = dict(_keys(where, params, {"line": {"start", "stop", "count"},
                                            "circle": {"centre", "radius_m", "count", "start_deg"},
                                            "spad_patch": {"centre", "counts", "pitch_m"}}[kind]))
        return getattr(layouts, kind)(**_generator(where, kind, params))
    require(isinstance(value, list) and len(value) >= 1, "setup.detector_spots", f"expected a "
            f"list of [x, y, z] spots or a generator, got {shown(value)}",
            "write e.g. [[-0.5, 0, 0]]")
    return [_point(f"setup.detector_spots[{i}]", p) for i, p in enumerate(value)]


def _generator(where: str, kind: str, params: dict) -> dict:
    """A spot generator's parameters, checked: points on the scene's scale, whole counts."""
    for key in ("start", "stop", "centre"):
        if key in params:
            params[key] = _point(f"{where}.{key}", params[key])
    for key in ("radius_m", "start_deg"):
        if key in params:
            params[key] = _number(f"{where}.{key}", params[key], f"{kind}.{key}"
                                  if key == "radius_m" else key)
    if "count" in params:
        params["count"] = whole_number(f"{where}.count", params["count"], 1, MAX_SPOTS)
    if "counts" in params:
        counts = params["counts"]
        ok = isinstance(counts, list) and len(counts) == 2
        require(ok, f"{where}.counts", f"expected [along x, along z], got {shown(counts)}",
                "write e.g. counts: [32, 32]")
        params["counts"] = [whole_number(f"{where}.counts[{i}]", c, 1, MAX_SPOTS)
                            for i, c in enumerate(counts)]
        require(math.prod(params["counts"]) <= MAX_SPOTS, f"{where}.counts", f"makes "
                f"{math.prod(params['counts'])} spots, more than {MAX_SPOTS}", "use fewer spots")
    if "pitch_m" in params:
        pitch = params["pitch_m"]
        pitch = pitch if isinstance(pitch, list) else [pitch]
        params["pitch_m"] = [_number(f"{where}.pitch_m", v, "spad_patch.pitch_m") for v in pitch]
    return params


def _setup(raw: dict):
    from ..physics.scene import Pulse, Setup
    raw = dict(_keys("setup", raw or {}, SETUP_KEYS))
    if "detector_spots" in raw:
        raw["detector_spots"] = _spots(raw["detector_spots"])
    if "laser_spot" in raw:
        raw["laser_spot"] = _point("setup.laser_spot", raw["laser_spot"])
    for key in sorted(SETUP_KEYS & {k[6:] for k in RANGES if k.count(".") == 1}):
        if key in raw:
            raw[key] = _number(f"setup.{key}", raw[key])
    if "pulse" in raw:
        pulse = dict(_keys("setup.pulse", raw["pulse"], {"fwhm_s", "energy_j", "power_w",
                                                         "rep_rate_hz"}))
        pulse = {k: _number(f"setup.pulse.{k}", v) for k, v in pulse.items()}
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
    require(shape in SHAPES, f"{where}.shape", f"unknown shape {shown(shape)}",
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
    require(isinstance(spec, dict), where, f"expected a mapping, got {shown(spec)}",
            "write e.g. {shape: sphere, radius_m: 0.3, position: [2, 4, 0]}")
    mesh = _mesh(where, spec, base, cell)
    centre = mesh.bounds.mean(axis=0)
    vertices = (mesh.vertices - centre) * _number(f"{where}.scale", spec.get("scale", 1.0))
    span = float(np.ptp(vertices, axis=0).max())
    require(span <= MAX_SCENE_M, f"{where}", f"spans {span:.4g} m, more than the "
            f"{MAX_SCENE_M:g} m a scene spans: that looks like a mesh in millimetres",
            "add scale: 0.001 (millimetres to metres)")
    if "rotation_deg" in spec:
        vertices = vertices @ _rotation(f"{where}.rotation_deg", spec["rotation_deg"]).T
    path = _trajectory(where, spec)
    start = path.at(0.0) if path is not None else spec.get("position", [4, 2, 0])
    mesh.vertices = vertices + _point(f"{where}.position", start)
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


def _time_axis(raw, setup, noise=None):
    from ..core.paths import TimeAxis, default_time_axis, simulation_bin
    raw = _keys("time_axis", raw or {}, {"dt_s", "t0_s", "n_bins", "max_hidden_path_m"})
    tdc = getattr(noise, "tdc_bin_s", None)  # photon counts: bins that sum into the TDC's
    dt = _number("time_axis.dt_s", raw.get("dt_s", 10e-12 if tdc is None else
                                           simulation_bin(tdc)))
    if "t0_s" in raw or "n_bins" in raw:
        require("t0_s" in raw and "n_bins" in raw, "time_axis", "t0_s and n_bins go together",
                "give both, or neither (then the window is derived)")
        return TimeAxis(_number("time_axis.t0_s", raw["t0_s"]), dt,
                        whole_number("time_axis.n_bins", raw["n_bins"], 2, 1 << 31, 2048))
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
        return PhotonCounter(**{k: _number(f"noise.photons.{k}", v)
                                for k, v in params.items()}), seed
    if "snr_db" in raw:
        return AWGN(_number("noise.snr_db", raw["snr_db"])), seed
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
    require(isinstance(occlusion, bool), "occlusion", f"must be true or false, got "
            f"{shown(occlusion)}", "write occlusion: true (the default) or false")
    scene = Scene(setup, placed[0], cell, more_targets=tuple(placed[1:]), occlusion=occlusion)
    noise, seed = _noise(raw.get("noise"))
    text = raw.get("description", "")
    require(isinstance(text, (str, int, float)), "description", f"expected text, got "
            f"{type(text).__name__}", "write description: a line of text (quote it if it has ':')")
    return SceneSpec(scene, _time_axis(raw.get("time_axis"), setup, noise), noise, seed,
                     str(text), tuple(paths))


def yaml_loader():
    """The YAML loader for users' files (nlos_cl.io.yamlfile: YAML 1.2 floats, bounded
    aliases and nesting, no duplicate keys)."""
    from .yamlfile import yaml_loader as loader
    return loader()


def read_yaml(path: Path, what: str = "scene file") -> dict:
    """A short YAML file (scene, study) as a mapping, with clear errors (nlos_cl.io.yamlfile)."""
    from .yamlfile import read_yaml as read
    return read(path, what)
