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
from . import sequences
from .objects import (
    CONFIG,
    apart,
    centre_in,
    corners,
    facing,
    log_u,
    placed,
    sized,
    tries,
    u,
)

__all__ = ["apart", "centre_in", "config", "corners", "draw", "family_of", "placed", "sized"]


def config() -> dict:
    return load_data(CONFIG, __package__)


def family_of(index: int, cfg: dict) -> str:
    return cfg["families"][index % len(cfg["families"])]


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
    return tries(make, f"{k} targets")


def _occluder(rng, cfg, fam, spots, target) -> dict | None:
    """A plate on the way from O to the target, moved across it, facing the wall, clear of
    the target by clear_m along that way."""
    c = np.asarray(target["centre"])
    way = c / np.linalg.norm(c)
    across = np.cross([0.0, 0.0, 1.0], way)
    across /= np.linalg.norm(across)
    p = fam["plate"]
    o = {"role": "occluder", "shape": "plate", "size": [round(u(rng, p["width_m"]), 4),
                                                         round(u(rng, p["height_m"]), 4)]}
    o["bound_m"] = 0.5 * math.hypot(*o["size"])
    centre = u(rng, fam["along"]) * c + u(rng, fam["aside_m"]) * across + \
        [0.0, 0.0, u(rng, fam["up_m"])]
    normal = facing(centre, spots, 0.0)
    o.update(centre=np.round(centre, 6).tolist(), yaw_deg=0.0, normal=np.round(normal, 6).tolist())
    if corners(o)[:, 1].min() < cfg["region"]["wall_gap_m"]:
        return None
    if (corners(o) @ way).max() + fam["clear_m"] > (corners(target) @ way).min():
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
        return {"objects": tries(make, "an occluder")}
    out = {"objects": _targets(rng, cfg, fam, spots, 1)}
    if family == "records":
        kind = fam["kinds"][(index // n) % len(fam["kinds"])]
        out["record"] = {"kind": kind, "after_m": round(u(rng, fam["after_m"]), 4)}
        if kind == "gated":
            out["record"]["open_before_m"] = round(u(rng, fam["open_before_m"]), 4)
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
        out["move_m"] = [round(u(rng, fam["move_m"]), 4) for _ in range(3)]
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
        scene = sequences.sequence(rng, cfg, fam, index // len(cfg["families"]), lay)
    else:
        scene = _static(rng, cfg, fam, family, int(index), lay)
    noise = {"seed": int(rng.integers(0, 2 ** 31 - 1))}
    if family == "bins":
        noise["photons"] = {"tdc_bin_s": float(f"{log_u(rng, fam['tdc_s']):.4g}")}
    elif family == "counts":
        noise["photons"] = {k: float(f"{log_u(rng, fam[k]):.4g}") for k in
                            ("n_pulses", "ambient_rate_hz", "dark_count_rate_hz")}
    else:
        noise["snr_db"] = round(u(rng, cfg["snr_db"]), 3)
    return {"index": int(index), "family": family, "master_seed": seed, "layout": lay,
            "record": None, "wall": None, "sequence": None, **scene, "noise": noise}
