"""The scenarios' scenes, drawn at random: `draw(index, master_seed)` is a pure function of its
arguments (and scenarios.yaml's ranges) returning plain data (lists, numbers, strings), so a CSV
row's index and seed re-draw it. Draw i is of family families[i % len(families)]; its random
stream is that of nlos_cl.simulation.draws.families.rng_of("scenarios-" + family, i, seed),
whose wall-spot layouts it reuses. Nothing here simulates: scenes turns a draw into files.

An object is {role, shape, centre, sizes, ...}: role "target" (a truth), "occluder" (a plate
between wall and target: a truth too, an object the answer should find) or "furniture"
(static clutter of a sequence, no truth); a mover has "path" [start, end]."""
from __future__ import annotations

import math

import numpy as np

from ....core.errors import require
from ....simulation.draws import families
from ..common import load_data

CONFIG = "scenarios.yaml"
LASER = families.LASER


def config() -> dict:
    return load_data(CONFIG, __package__)


def family_of(index: int, cfg: dict) -> str:
    return cfg["families"][index % len(cfg["families"])]


def _u(rng, pair) -> float:
    return float(rng.uniform(*pair))


def _log_u(rng, pair) -> float:
    return math.exp(_u(rng, [math.log(v) for v in pair]))


def _tries(make, what: str):
    """The first value `make` gives that is not None (rejection sampling on the draw's stream)."""
    for _ in range(families.TRIES):
        value = make()
        if value is not None:
            return value
    require(False, CONFIG, f"{what}: no draw met the constraints in {families.TRIES} tries",
            "widen the ranges in nlos_cl/apps/reproduce/scenarios/scenarios.yaml")


def sized(shape: str, rng, cfg) -> dict:
    """An object's shape and sizes (no place yet) and its bounding radius."""
    z = cfg["sizes"][shape]
    if shape == "plate":
        size = [round(_u(rng, z["width_m"]), 4), round(_u(rng, z["height_m"]), 4)]
    elif shape == "box":
        size = [round(_u(rng, z["side_m"]), 4) for _ in range(3)]
    elif shape == "cabinet":
        size = [round(_u(rng, z[k]), 4) for k in ("width_m", "depth_m", "height_m")]
    else:  # person: an upright capsule of this radius and overall height
        r, h = round(_u(rng, z["radius_m"]), 4), round(_u(rng, z["height_m"]), 4)
        return {"shape": shape, "radius_m": r, "height_m": h, "bound_m": math.hypot(r, h / 2)}
    return {"shape": shape, "size": size, "bound_m": 0.5 * float(np.linalg.norm(size))}


def facing(centre, spots, yaw_deg: float) -> np.ndarray:
    """The horizontal unit vector from `centre` towards the centroid of O and the spots, turned
    by yaw_deg about z."""
    towards = np.vstack([LASER, spots]).mean(axis=0) - np.asarray(centre)
    a = math.atan2(towards[1], towards[0]) + math.radians(yaw_deg)
    return np.array([math.cos(a), math.sin(a), 0.0])


def corners(o: dict, centre=None) -> np.ndarray:
    """The corners of the object's oriented bounding box (a plate's four)."""
    c = np.asarray(o["centre"] if centre is None else centre, float)
    if o["shape"] == "person":
        half = np.array([o["radius_m"], o["radius_m"], o["height_m"] / 2])
        yaw = 0.0
    elif o["shape"] == "plate":
        half = np.array([0.0, o["size"][0] / 2, o["size"][1] / 2])
        yaw = math.atan2(o["normal"][1], o["normal"][0])
    else:
        half, yaw = np.asarray(o["size"]) / 2, math.radians(o["yaw_deg"])
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
    rot = np.array([[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0],
                    [0, 0, 1]])
    return np.unique(signs * half, axis=0) @ rot.T + c


def placed(o: dict, centre, rng, cfg, spots) -> dict | None:
    """`o` at `centre`, turned (plates face O and every spot: they return light to each); None
    where it would reach within wall_gap_m of the wall or no yaw faces the spots."""
    reg = cfg["region"]
    out = {**o, "centre": np.round(np.asarray(centre, float), 6).tolist()}
    if o["shape"] == "plate":
        for _ in range(families.FACING_TRIES):
            yaw = _u(rng, (-reg["yaw_deg"], reg["yaw_deg"]))
            normal = facing(centre, spots, yaw)
            if families.facing_cos(normal, np.asarray(centre, float), spots) >= \
                    reg["min_facing_cos"]:
                break
        else:
            return None
        out.update(yaw_deg=round(yaw, 3), normal=np.round(normal, 6).tolist())
    elif o["shape"] in ("box", "cabinet"):
        out["yaw_deg"] = round(_u(rng, (-reg["yaw_deg"], reg["yaw_deg"])), 3)
    if corners(out)[:, 1].min() < reg["wall_gap_m"]:
        return None
    return out


def centre_in(rng, cfg) -> np.ndarray:
    reg = cfg["region"]
    return np.array([_u(rng, reg["x"]), _u(rng, reg["y"]), _u(rng, reg["z"])])


def apart(a: dict, b: dict, gap: float) -> bool:
    d = np.linalg.norm(np.subtract(a["centre"], b["centre"]))
    return bool(d >= a["bound_m"] + b["bound_m"] + gap)


def _targets(rng, cfg, fam, spots, k: int, role="target") -> list:
    """k objects of the family's shapes (sizes drawn once), placed apart at random."""
    shapes = [sized(str(rng.choice(fam["shapes"])), rng, cfg) for _ in range(k)]
    gap = fam.get("min_gap_m", 0.0)

    def make():
        out = []
        for o in shapes:
            p = placed({"role": role, **o}, centre_in(rng, cfg), rng, cfg, spots)
            if p is None or not all(apart(p, q, gap) for q in out):
                return None
            out.append(p)
        return out
    return _tries(make, f"{k} targets")


def _occluder(rng, cfg, fam, spots, target) -> dict | None:
    """A plate on the way from O to the target, moved across it, facing the wall, clear of
    the target by clear_m along that way."""
    c = np.asarray(target["centre"])
    u = c / np.linalg.norm(c)
    across = np.cross([0.0, 0.0, 1.0], u)
    across /= np.linalg.norm(across)
    p = fam["plate"]
    o = {"role": "occluder", "shape": "plate", "size": [round(_u(rng, p["width_m"]), 4),
                                                         round(_u(rng, p["height_m"]), 4)]}
    o["bound_m"] = 0.5 * math.hypot(*o["size"])
    centre = _u(rng, fam["along"]) * c + _u(rng, fam["aside_m"]) * across + \
        [0.0, 0.0, _u(rng, fam["up_m"])]
    normal = facing(centre, spots, 0.0)
    o.update(centre=np.round(centre, 6).tolist(), yaw_deg=0.0, normal=np.round(normal, 6).tolist())
    if corners(o)[:, 1].min() < cfg["region"]["wall_gap_m"]:
        return None
    if (corners(o) @ u).max() + fam["clear_m"] > (corners(target) @ u).min():
        return None
    return o


def _static(rng, cfg, fam, family: str, index: int, lay) -> dict:
    spots = np.asarray(lay["spots"])
    n = len(cfg["families"])
    if family == "multi":
        return {"objects": _targets(rng, cfg, fam, spots, fam["targets"][(index // n) %
                                                                        len(fam["targets"])])}
    if family == "occluders":
        def make():
            target = _targets(rng, cfg, fam, spots, 1)[0]
            occ = _occluder(rng, cfg, fam, spots, target)
            return None if occ is None else [target, occ]
        return {"objects": _tries(make, "an occluder")}
    out = {"objects": _targets(rng, cfg, fam, spots, 1)}
    if family == "records":
        kind = fam["kinds"][(index // n) % len(fam["kinds"])]
        out["record"] = {"kind": kind, "after_m": round(_u(rng, fam["after_m"]), 4)}
        if kind == "gated":
            out["record"]["open_before_m"] = round(_u(rng, fam["open_before_m"]), 4)
    elif family == "walls":
        out["wall"] = _wall(rng, fam, fam["kinds"][(index // n) % len(fam["kinds"])], len(spots))
    return out


def rotation(rng) -> np.ndarray:
    """A rotation drawn uniformly (a random unit quaternion)."""
    w, x, y, z = (q := rng.normal(size=4)) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _wall(rng, fam, kind: str, n_spots: int) -> dict:
    """tilted: any rotation; moved: any translation; both; bumpy: the laser spot's and every
    detector spot's distance off the wall plane (y), up to bump_m either way."""
    out = {"kind": kind, "rotation": np.eye(3).tolist(), "move_m": [0.0, 0.0, 0.0]}
    if kind == "bumpy":
        b = fam["bump_m"]
        out["bumps_m"] = np.round(rng.uniform(-b, b, n_spots + 1), 5).tolist()
        return out
    if "tilted" in kind:
        out["rotation"] = np.round(rotation(rng), 9).tolist()
    if "moved" in kind:
        out["move_m"] = [round(_u(rng, fam["move_m"]), 4) for _ in range(3)]
    return out


def draw(index: int, master_seed: int | None = None, cfg: dict | None = None) -> dict:
    """The scene of draw `index` under `master_seed` (scenarios.yaml's by default)."""
    require(isinstance(index, (int, np.integer)) and index >= 0, "index",
            f"must be a non-negative integer, got {index!r}", "pass e.g. 0")
    cfg = config() if cfg is None else cfg
    seed = cfg["master_seed"] if master_seed is None else int(master_seed)
    family = family_of(int(index), cfg)
    rng = families.rng_of("scenarios-" + family, int(index), seed)
    fam = cfg[family]
    lay = families.layout(str(rng.choice(fam["layouts"])), rng, cfg, fam.get("min_spots", 1))
    if family == "clutter":
        from .sequences import sequence  # movers and furniture
        scene = sequence(rng, cfg, fam, index // len(cfg["families"]), lay)
    else:
        scene = _static(rng, cfg, fam, family, int(index), lay)
    noise = {"seed": int(rng.integers(0, 2 ** 31 - 1))}
    if family == "bins":
        noise["photons"] = {"tdc_bin_s": float(f"{_log_u(rng, fam['tdc_s']):.4g}")}
    elif family == "counts":
        noise["photons"] = {k: float(f"{_log_u(rng, fam[k]):.4g}") for k in
                            ("n_pulses", "ambient_rate_hz", "dark_count_rate_hz")}
    else:
        noise["snr_db"] = round(_u(rng, cfg["snr_db"]), 3)
    return {"index": int(index), "family": family, "master_seed": seed, "layout": lay,
            "record": None, "wall": None, "sequence": None, **scene, "noise": noise}
