"""The objects of a scenario draw (plain data): an object's shape and sizes drawn (`sized`),
placed and turned (`placed`; plates face O and every spot), its bounding-box corners, and the
rejection loop every draw uses (`tries`). Shared by draws and sequences."""
from __future__ import annotations

import math

import numpy as np

from ....core.errors import require
from ....simulation.draws import families

CONFIG = "scenarios.yaml"
LASER = families.LASER


def u(rng, pair) -> float:
    return float(rng.uniform(*pair))


def log_u(rng, pair) -> float:
    return math.exp(u(rng, [math.log(v) for v in pair]))


def tries(make, what: str):
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
        size = [round(u(rng, z["width_m"]), 4), round(u(rng, z["height_m"]), 4)]
    elif shape == "box":
        size = [round(u(rng, z["side_m"]), 4) for _ in range(3)]
    elif shape == "cabinet":
        size = [round(u(rng, z[k]), 4) for k in ("width_m", "depth_m", "height_m")]
    else:  # person: an upright capsule of this radius and overall height
        r, h = round(u(rng, z["radius_m"]), 4), round(u(rng, z["height_m"]), 4)
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
            yaw = u(rng, (-reg["yaw_deg"], reg["yaw_deg"]))
            normal = facing(centre, spots, yaw)
            if families.facing_cos(normal, np.asarray(centre, float), spots) >= \
                    reg["min_facing_cos"]:
                break
        else:
            return None
        out.update(yaw_deg=round(yaw, 3), normal=np.round(normal, 6).tolist())
    elif o["shape"] in ("box", "cabinet"):
        out["yaw_deg"] = round(u(rng, (-reg["yaw_deg"], reg["yaw_deg"])), 3)
    if corners(out)[:, 1].min() < reg["wall_gap_m"]:
        return None
    return out


def centre_in(rng, cfg) -> np.ndarray:
    reg = cfg["region"]
    return np.array([u(rng, reg["x"]), u(rng, reg["y"]), u(rng, reg["z"])])


def apart(a: dict, b: dict, gap: float) -> bool:
    d = np.linalg.norm(np.subtract(a["centre"], b["centre"]))
    return bool(d >= a["bound_m"] + b["bound_m"] + gap)
