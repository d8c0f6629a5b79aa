"""The scenes of `reproduce draws`, drawn at random: `draw(family, index, master_seed)` is a
pure function of its arguments (and draws.yaml's ranges) that returns plain data (lists,
numbers, strings), so the same seed gives the same scene and a CSV row names all it needs to
re-run its draw alone. Nothing here simulates; scenes turns a draw into a Scene.

A draw's own random stream is SeedSequence((master_seed, crc32(family), index)): draws of one
family do not shift when another family's count changes, and draw 17 is draw 17 whatever ran
before it. Rejection loops (spots too close, targets overlapping) use that stream only, so they
stay deterministic."""
from __future__ import annotations

import math
import zlib
from importlib import resources

import numpy as np

from ...core.errors import require
from ...io.yamlfile import load_text
from . import crossings

FAMILIES = ("one", "multi", "closed", "mismatch", "crossings", "counts")
LASER = np.zeros(3)  # the paper's laser spot O, which every draw keeps
TRIES = 1000  # rejection-sampling attempts before a draw gives up (a range that cannot be met)
FACING_TRIES = 50  # yaws tried for a crossing plate before its paths are drawn again
CONFIG = "draws.yaml"


def config() -> dict:
    """draws.yaml, the ranges every draw is taken from (package data: ships in the wheel)."""
    return load_text(resources.files(__package__).joinpath(CONFIG).read_text("utf-8"), CONFIG)


def rng_of(family: str, index: int, master_seed: int) -> np.random.Generator:
    seq = np.random.SeedSequence((int(master_seed), zlib.crc32(family.encode()), int(index)))
    return np.random.default_rng(seq)


def _u(rng, pair) -> float:
    return float(rng.uniform(*pair))


def _spread(points) -> float:
    """The rms distance of the points from their best line: 0 for collinear points."""
    centred = points - points.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False)
    return float(s[1] / math.sqrt(len(points))) if len(s) > 1 else 0.0


def _spots_ok(spots, wall, min_apart=None) -> bool:
    """On the wall window, off the laser spot, apart, and not (with O) on one line."""
    apart = wall["min_apart_m"] if min_apart is None else min_apart
    in_x = np.all((spots[:, 0] >= wall["x"][0]) & (spots[:, 0] <= wall["x"][1]))
    in_z = np.all((spots[:, 2] >= wall["z"][0]) & (spots[:, 2] <= wall["z"][1]))
    if not (in_x and in_z) or np.min(np.linalg.norm(spots - LASER, axis=1)) < \
            wall["min_from_laser_m"]:
        return False
    d = np.linalg.norm(spots[:, None] - spots[None], axis=2) + np.eye(len(spots)) * 1e9
    return bool(d.min() >= apart and _spread(np.vstack([LASER, spots])) >= wall["min_spread_m"])


def _wall_point(rng, wall) -> np.ndarray:
    return np.array([_u(rng, wall["x"]), 0.0, _u(rng, wall["z"])])


def _rejected(make, ok, what: str):
    for _ in range(TRIES):
        value = make()
        if ok(value):
            return value
    require(False, "draws.yaml", f"{what}: no draw met the constraints in {TRIES} tries",
            "widen the ranges in nlos_cl/simulation/draws/draws.yaml")


def layout(kind: str, rng, cfg, min_spots: int = 1) -> dict:
    """{kind, spots (list of [x, 0, z]), collinear, ...the drawn parameters}."""
    wall, p = cfg["wall"], cfg["layouts"][kind]
    if kind == "line":  # the paper's three spots in a line through O, turned and spaced
        angle = float(rng.choice(p["angles_deg"]))
        spacing, first = _u(rng, p["spacing_m"]), _u(rng, p["first_m"])
        a = math.radians(angle)
        u = np.array([math.cos(a), 0.0, math.sin(a)])
        spots = np.array([(first + i * spacing) * u for i in range(3)])
        spots[np.abs(spots) < 1e-12] = 0.0
        return {"kind": kind, "spots": spots.round(6).tolist(), "collinear": True,
                "angle_deg": angle, "spacing_m": spacing, "first_m": first}
    if kind == "circle":
        def make():
            count = max(int(rng.integers(p["count"][0], p["count"][1] + 1)), min_spots)
            centre = (_u(rng, p["centre_x"]), 0.0, _u(rng, p["centre_z"]))
            r, start = _u(rng, p["radius_m"]), _u(rng, (0.0, 360.0))
            a = math.radians(start) + 2 * math.pi * np.arange(count) / count
            return np.asarray(centre) + r * np.stack([np.cos(a), 0 * a, np.sin(a)], axis=1)
        spots = _rejected(make, lambda s: _spots_ok(s, wall), "circle layout")
    elif kind == "spad":
        def make():
            nx, nz = (int(v) for v in rng.integers(p["count"][0], p["count"][1] + 1, 2))
            pitch = _u(rng, p["pitch_m"])
            centre = np.array([_u(rng, p["centre_x"]), 0.0, _u(rng, p["centre_z"])])
            x = (np.arange(nx) - (nx - 1) / 2) * pitch
            z = (np.arange(nz) - (nz - 1) / 2) * pitch
            xx, zz = np.meshgrid(x, z, indexing="ij")
            return centre + np.stack([xx.ravel(), 0 * xx.ravel(), zz.ravel()], axis=1)
        spots = _rejected(make, lambda s: _spots_ok(s, wall, min_apart=0.0), "SPAD patch")
    else:  # triangle (3 spots) or random (count drawn)
        lo, hi = (3, 3) if kind == "triangle" else p["count"]
        apart = p.get("min_apart_m")

        def make():
            count = max(int(rng.integers(lo, hi + 1)), min_spots)
            return np.array([_wall_point(rng, wall) for _ in range(count)])
        spots = _rejected(make, lambda s: _spots_ok(s, wall, apart), f"{kind} layout")
    return {"kind": kind, "spots": np.round(spots, 6).tolist(), "collinear": False}


def _facing_normal(centre, spots, yaw_deg: float) -> np.ndarray:
    """The horizontal unit vector from `centre` towards the centroid of O and the spots,
    turned by yaw_deg about z."""
    towards = np.vstack([LASER, spots]).mean(axis=0) - centre
    base = math.atan2(towards[1], towards[0]) + math.radians(yaw_deg)
    return np.array([math.cos(base), math.sin(base), 0.0])


def facing_cos(normal, centre, spots) -> float:
    """The smallest cosine between `normal` and the way from `centre` to O or any spot."""
    ways = np.vstack([LASER, spots]) - centre
    ways /= np.linalg.norm(ways, axis=1, keepdims=True)
    return float((ways @ normal).min())


def centre_in(rng, cfg, lay) -> np.ndarray:
    """A target centre in the region; collinear spots see no height (a line along x) or no
    x (a line along z): the centre is then on the plane the search holds (z = 0 or x = 0)."""
    reg = cfg["region"]
    c = np.array([_u(rng, reg["x"]), _u(rng, reg["y"]), _u(rng, reg["z"])])
    if lay["collinear"]:
        along_x = abs(math.cos(math.radians(lay["angle_deg"]))) > 0.5
        c[2 if along_x else 0] = 0.0
    return c


def target(shape: str, rng, cfg, lay, centre, sides=None) -> dict:
    """One target: {shape, centre, and its sizes; plates and boxes their yaw and normal}."""
    reg, p = cfg["region"], cfg["shapes"][shape]
    spots = np.asarray(lay["spots"])
    out = {"shape": shape, "centre": np.round(centre, 6).tolist()}
    if shape in ("plate", "box"):
        span = sides or p["side_m"]
        count = 2 if shape == "plate" else 3
        out["size"] = [round(_u(rng, span), 4) for _ in range(count)]
        for _ in range(TRIES):  # a plate must face O and every spot, to return light to them
            yaw = _u(rng, (-reg["yaw_deg"], reg["yaw_deg"]))
            normal = _facing_normal(centre, spots, yaw)
            if shape == "box" or facing_cos(normal, centre, spots) >= reg["min_facing_cos"]:
                break
        else:
            yaw, normal = 0.0, _facing_normal(centre, spots, 0.0)
        out.update(yaw_deg=round(yaw, 3), normal=np.round(normal, 6).tolist())
    elif shape == "sphere":
        out["radius_m"] = round(_u(rng, p["radius_m"]), 4)
    else:
        out.update(radius_m=round(_u(rng, p["radius_m"]), 4),
                   height_m=round(_u(rng, p["height_m"]), 4))
    return out


def bounding_radius(t: dict) -> float:
    if t["shape"] in ("plate", "box"):
        return 0.5 * float(np.linalg.norm(t["size"]))
    if t["shape"] == "sphere":
        return t["radius_m"]
    return math.hypot(t["radius_m"], 0.5 * t["height_m"])


def _one(rng, cfg, fam) -> dict:
    kind = str(rng.choice(fam["layouts"]))
    lay = layout(kind, rng, cfg)
    shape = str(rng.choice(fam["shapes"]))
    return {"layout": lay, "targets": [target(shape, rng, cfg, lay, centre_in(rng, cfg, lay))]}


def _shadows(targets) -> bool:
    """Whether a target's bounding sphere crosses the way from another's centre to O."""
    for a in targets:
        for b in targets:
            if a is b:
                continue
            ca, cb = np.asarray(a["centre"]), np.asarray(b["centre"])
            t = np.clip(np.dot(cb - ca, LASER - ca) / np.dot(LASER - ca, LASER - ca), 0, 1)
            if np.linalg.norm(ca + t * (LASER - ca) - cb) < bounding_radius(b):
                return True
    return False


def _multi(rng, cfg, fam, index) -> dict:
    kind = str(rng.choice(fam["layouts"]))
    lay = layout(kind, rng, cfg, min_spots=fam["min_spots"])
    k = fam["targets"][index % len(fam["targets"])]

    def make():
        return [target("plate", rng, cfg, lay, centre_in(rng, cfg, lay), fam["plate_side_m"])
                for _ in range(k)]

    def ok(ts):
        for i, a in enumerate(ts):
            for b in ts[i + 1:]:
                d = np.linalg.norm(np.subtract(a["centre"], b["centre"]))
                if d < fam["min_apart_m"] or d < bounding_radius(a) + bounding_radius(b):
                    return False
        return not _shadows(ts)
    return {"layout": lay, "targets": _rejected(make, ok, f"{k} targets")}


def _mismatch(rng, cfg, fam, index) -> dict:
    sub = fam["subfamilies"][index % len(fam["subfamilies"])]
    scene = _one(rng, cfg, cfg["families"]["one"])
    m = {"kind": sub}
    if sub == "pulse":
        m["fwhm_ps"] = round(_u(rng, fam["pulse_fwhm_ps"]), 2)
    elif sub == "irf_tail":
        m.update(tau_ps=round(_u(rng, fam["irf_tau_ps"]), 2),
                 share=round(_u(rng, fam["irf_tail_share"]), 4))
    elif sub == "peak_noise":
        m["peak_snr_db"] = round(_u(rng, fam["peak_snr_db"]), 3)
    elif sub == "brdf":
        g = fam["ggx"]
        spec, rough, diff = (_u(rng, g[k]) for k in ("specular", "roughness", "diffuse"))
        m.update(specular=round(spec, 4), roughness=round(rough, 4),
                 diffuse=round(min(diff, 1.0 - spec), 4))
    else:
        m.update(ambient_share=round(_u(rng, fam["ambient_share"]), 5),
                 delay_ns=round(_u(rng, fam["fourth_delay_ns"]), 4),
                 sigma_ns=round(_u(rng, fam["fourth_sigma_ns"]), 4),
                 share=round(_u(rng, fam["fourth_share"]), 4))
    return {**scene, "mismatch": m}


def _counts(rng, cfg, fam) -> dict:
    """A `one` scene whose frame is photon counts (scenes.noisy): signal photons per
    detector, ambient rate and TDC bin drawn log-uniform / uniform (draws.yaml counts)."""
    scene = _one(rng, cfg, cfg["families"]["one"])
    photons = math.exp(_u(rng, [math.log(v) for v in fam["signal_photons"]]))
    ambient = math.exp(_u(rng, [math.log(v) for v in fam["ambient_rate_hz"]]))
    counting = {"signal_photons": round(photons, 1), "ambient_rate_hz": round(ambient, 1),
                "tdc_ps": int(round(_u(rng, fam["tdc_ps"])))}
    return {**scene, "counting": counting}


def _facing_yaw(rng, reg, path, spots):
    """A yaw (and normal) for an upright plate walking `path` that faces O and every spot
    from both ends of it (and so from all of it: along a line the angle to a point turns one
    way), or None."""
    middle = np.mean(path, axis=0)
    for _ in range(FACING_TRIES):
        yaw = _u(rng, (-reg["yaw_deg"], reg["yaw_deg"]))
        normal = _facing_normal(middle, spots, yaw)
        if min(facing_cos(normal, p, spots) for p in path) >= reg["min_facing_cos"]:
            return yaw, normal
    return None


def _crossings(rng, cfg, fam) -> dict:
    """Two upright plates on straight paths that cross (crossings), over fam's frames:
    each target's `centre` is where its path starts, `path` its [start, end] in 3-D."""
    kind = str(rng.choice(fam["layouts"]))
    # the existing generators, held at exactly `spots` spots
    held = {**cfg["layouts"][kind], "count": [fam["spots"], fam["spots"]]}
    lay = layout(kind, rng, {**cfg, "layouts": {**cfg["layouts"], kind: held}})
    reg, spots = cfg["region"], np.asarray(lay["spots"])
    span_s = (fam["frames"] - 1) / fam["fps"]

    def make():
        sizes = [[round(_u(rng, fam["plate_side_m"]), 4) for _ in range(2)] for _ in range(2)]
        geometry = crossings.crossing_paths(rng, fam, reg, span_s, [0.5 * s[0] for s in sizes])
        if geometry is None:
            return None
        targets = []
        for size, xy in zip(sizes, geometry["paths"]):
            z = _u(rng, reg["z"])  # each walks at its own height
            path = np.array([[*p, z] for p in xy])
            facing = _facing_yaw(rng, reg, path, spots)
            if facing is None:
                return None
            targets.append({"shape": "plate", "centre": np.round(path[0], 6).tolist(),
                            "size": size, "yaw_deg": round(facing[0], 3),
                            "normal": np.round(facing[1], 6).tolist(),
                            "path": np.round(path, 6).tolist()})
        crossing = {k: v for k, v in geometry.items() if k != "paths"}  # the targets hold them
        return {"layout": lay, "targets": targets, "crossing": crossing}
    scene = _rejected(make, lambda s: s is not None, "crossing paths")
    frames = {k: fam[k] for k in ("frames", "fps", "dt_s", "facet_m", "first_frame")}
    return {**scene, "frames": frames}


def draw(family: str, index: int, master_seed: int | None = None, cfg: dict | None = None
         ) -> dict:
    """The scene of draw `index` of `family` under `master_seed` (draws.yaml's by default)."""
    require(family in FAMILIES, "family", f"unknown family {family!r}", f"use one of {FAMILIES}")
    require(isinstance(index, (int, np.integer)) and index >= 0, "index",
            f"must be a non-negative integer, got {index!r}", "pass e.g. 0")
    cfg = config() if cfg is None else cfg
    seed = cfg["master_seed"] if master_seed is None else int(master_seed)
    rng = rng_of(family, index, seed)
    fam = cfg["families"][family]
    if family == "multi":
        scene = _multi(rng, cfg, fam, index)
    elif family == "mismatch":
        scene = _mismatch(rng, cfg, fam, index)
    elif family == "crossings":
        scene = _crossings(rng, cfg, fam)
    elif family == "counts":
        scene = _counts(rng, cfg, fam)
    else:
        scene = _one(rng, cfg, fam)
    scene.setdefault("mismatch", None)
    return {"family": family, "index": int(index), "master_seed": seed, **scene,
            "snr_db": round(_u(rng, cfg["snr_db"]), 3),
            "noise_seed": int(rng.integers(0, 2 ** 31 - 1))}
