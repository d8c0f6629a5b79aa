"""tracking.yaml, checked and turned into what `reproduce tracking` runs: setups, paths (as
bound families and as trajectories), the motion model and the tracker's settings.

Every key is checked before anything runs, so that a bad case fails in a second with one line
naming it (`tracking.yaml lines.frames: expected ...`) rather than after an hour of frames."""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

import nlos_cl as nl
from nlos_cl.core.errors import require
from nlos_cl.physics.layouts import circle
from nlos_cl.tracking import ConstantVelocity, Trajectory, bounds

from ..common import load_data

SECTIONS = ("speed", "memory", "lines", "synthetic", "box", "crossing")
ESTIMATORS = ("paper", "model")
BOX_CASES = ("no box", "no removal", "reference", "running mean")


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _integer(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _vector(n, test=_number):
    return lambda v: isinstance(v, list) and len(v) == n and all(test(x) for x in v)


def _positive(v) -> bool:
    return _number(v) and v > 0


# leaf kinds: (test, what the value must be, an example for the fix)
KINDS = {
    "number": (_number, "a finite number", "10"),
    "positive": (_positive, "a positive number", "0.1"),
    "count": (lambda v: _integer(v) and v >= 1, "a positive integer", "20"),
    "index": (lambda v: _integer(v) and v >= 0, "a non-negative integer", "1"),
    "bool": (lambda v: isinstance(v, bool), "true or false", "true"),
    "xy": (_vector(2), "[x, y] in metres", "[3.0, 1.5]"),
    "xyz": (_vector(3), "[x, y, z] in metres", "[2.0, 1.0, 0.0]"),
    "size2": (_vector(2, _positive), "[width, height], positive metres", "[0.3, 0.3]"),
    "size3": (_vector(3, _positive), "[x, y, z] sizes, positive metres", "[0.5, 0.5, 1.0]"),
    "range": (lambda v: _vector(2)(v) and v[0] < v[1], "[low, high] with low < high",
              "[1.5, 5.5]"),
    "pair": (_vector(2), "two numbers", "[0, 90]"),
    "positives": (lambda v: isinstance(v, list) and bool(v) and all(_positive(x) for x in v),
                  "a non-empty list of positive numbers", "[0.01, 0.047]"),
    "points": (lambda v: isinstance(v, list) and bool(v) and all(_vector(3)(p) for p in v),
               "a non-empty list of [x, y, z] points", "[[-0.5, 0, 0], [-1.0, 0, 0]]"),
    "two segments": (lambda v: isinstance(v, list) and len(v) == 2 and all(
        isinstance(s, list) and len(s) == 2 and all(_vector(3)(p) for p in s) for s in v),
        "two [start, end] pairs of [x, y, z] points",
        "[[[2.5, 2.0, 0], [3.5, 3.0, 0]], [[2.5, 3.0, 0], [3.5, 2.0, 0]]]"),
}


def _names(allowed=None, table=None):
    """A list of names from `allowed`, or of the keys of the config's `table`."""
    def check(where, value, cfg):
        known = list(allowed or cfg.get(table, {}))
        require(isinstance(value, list) and bool(value), where,
                f"expected a non-empty list of names, got {value!r}", f"write e.g. [{known[0]}]")
        bad = [v for v in value if v not in known]
        require(not bad, where, f"unknown name {bad[:1]}", f"use some of {known}")
    return check


def _name(table):
    def check(where, value, cfg):
        known = list(cfg.get(table, {}))
        require(value in known, where, f"unknown {table[:-1]} {value!r}", f"use one of {known}")
    return check


def _one_of(common, **shapes):
    """A mapping with `common`'s keys and exactly one of `shapes` (e.g. line or circle)."""
    def check(where, value, cfg):
        _check(where, value, dict, cfg)
        given = [k for k in shapes if k in value]
        require(len(given) == 1, where, f"needs exactly one of {', '.join(shapes)}",
                f"give {_at(where, next(iter(shapes)))} or another of {list(shapes)}")
        _check(where, value, {**common, given[0]: shapes[given[0]]}, cfg)
    return check


def _each(schema):
    """A mapping of user-chosen names, each value checked against `schema`."""
    def check(where, value, cfg):
        _check(where, value, dict, cfg)
        require(bool(value), where, "is empty", "name at least one entry")
        for key, item in value.items():
            _check(_at(where, key), item, schema, cfg)
    return check


SCHEMA = {
    "sections": _names(SECTIONS),
    "frames": {"fps": "positive", "dt_s": "positive", "facet_m": "positive", "snr_db": "number"},
    "grid": {"x": "range", "y": "range", "step_m": "positive"},
    "target_size_m": "size2",
    "max_accel_m_s2": "positive",
    "tracker": {"max_birge_ratio": "positive", "max_misses": "count", "warm_start": "bool"},
    "lag_frames": "index", "first_frame": "index",
    "goal": {"ratio": "positive", "max_m": "positive"},
    "layouts": _each(_one_of({}, spots="points", circle={"centre": "xyz", "radius_m": "positive",
                                                         "count": "count"})),
    "path_span_s": "positive",
    "paths": _each(_one_of({"waypoints": "count"}, line={"start": "xy", "stop": "xy"},
                           circle={"centre": "xy", "radius_m": "positive", "phase_deg": "pair"})),
    "lines": {"paths": _names(table="paths"), "layouts": _names(table="layouts"),
              "estimators": _names(ESTIMATORS), "frames": "count", "seed": "index"},
    "synthetic": {"paths": _names(table="paths"), "frames": "count", "seeds": "count",
                  "sigma_m": "positive", "accel_sigmas": "positives",
                  "imm_accel_sigmas": "pair"},
    "box": {"layout": _name("layouts"), "path": _name("paths"), "frames": "count",
            "seed": "index", "estimators": _names(ESTIMATORS),
            "clutter": {"size_m": "size3", "centre": "xyz"}, "reference_frames": "count",
            "reference_seed": "index", "running_mean_alpha": "positive",
            "cases": _names(BOX_CASES)},
    "crossing": {"layout": _name("layouts"), "frames": "count", "seeds": "count",
                 "size_m": "size2", "paths": "two segments", "check_frame": "index",
                 "radius_m": "positive"},
    "speed": {"bins": "count", "grid_cells": "count",
              "frames": {"paper": "count", "model": "count"}},
    "memory": {"frames": "count", "bins": "count", "grid_cells": "count"},
}


def _at(where: str, key) -> str:
    """The field's name in messages: 'tracking.yaml lines.frames' (the file, then the keys)."""
    return f"{where}{key}" if where[-1] in " ." else f"{where}.{key}"


def _check(where, value, schema, cfg) -> None:
    """Check `value` against `schema`: a dict (exactly these keys), a leaf kind, a function."""
    if callable(schema) and schema is not dict:
        return schema(where, value, cfg)
    if isinstance(schema, str):
        test, what, example = KINDS[schema]
        require(test(value), where, f"expected {what}, got {value!r}",
                f"write e.g. {re.split('[ .]', where)[-1]}: {example}")
        return None
    require(isinstance(value, dict), where, f"expected a mapping, got {value!r}",
            "write it as `key: value` lines")
    if schema is dict:
        return None
    for key in value:
        require(key in schema, _at(where, key), "is not a known key",
                f"use the keys {list(schema)}")
    for key, sub in schema.items():
        require(key in value, _at(where, key), "is missing",
                "add it (the package's tracking.yaml has every key)")
        _check(_at(where, key), value[key], sub, cfg)
    return None


def validate(data: dict, where: str = "tracking.yaml ") -> dict:
    """`data` (tracking.yaml's content) checked key by key; InputError names the first bad one."""
    _check(where, data, SCHEMA, data)
    return data


def config(quick: bool = False, data: dict | None = None) -> dict:
    """tracking.yaml (or `data` in its form), checked; with `quick`, its `quick` sections merged
    over the full ones, key by key, and checked again (an error there names quick.KEY)."""
    data = dict(load_data("tracking.yaml", __package__) if data is None else data)
    over = data.pop("quick", {})
    validate(data)
    _check("tracking.yaml quick", over, dict, data)  # a mapping of sections
    for key in over:
        require(isinstance(data.get(key), dict), f"tracking.yaml quick.{key}",
                "is not a section of the full setting",
                f"use one of {[k for k, v in data.items() if isinstance(v, dict)]}")
    if not quick:
        return data
    merged = {**data, **{k: {**data[k], **v} if isinstance(v, dict) else v
                         for k, v in over.items()}}
    return validate(merged, "tracking.yaml quick.")


@dataclass(frozen=True)
class Common:
    """What every case shares: frames, the search grid, the motion model, tracker settings."""

    fps: float
    dt_s: float
    facet_m: float
    snr_db: float
    grid: nl.Grid
    motion: ConstantVelocity
    tracker: dict  # Tracker keyword arguments
    lag: int
    first: int
    goal: dict

    @classmethod
    def of(cls, cfg: dict, cold: bool = False) -> "Common":
        """`cold`: every model fit from its frame alone (warm_start=False)."""
        f, g = cfg["frames"], cfg["grid"]
        grid = nl.Grid.from_ranges(x=tuple(g["x"]), y=tuple(g["y"]), step_m=g["step_m"])
        motion = ConstantVelocity(accel_sigma=cfg["max_accel_m_s2"] * math.sqrt(1 / f["fps"]))
        tracker = {**cfg["tracker"], **({"warm_start": False} if cold else {})}
        return cls(f["fps"], f["dt_s"], f["facet_m"], f["snr_db"], grid, motion, tracker,
                   cfg["lag_frames"], cfg["first_frame"], cfg["goal"])

    def walker(self, cfg: dict, position) -> nl.Target:
        w, h = cfg["target_size_m"]
        return nl.Target(nl.rectangle(w, h, centre=position, cell_m=self.facet_m))


def setup(cfg: dict, name: str) -> nl.Setup:
    spec = cfg["layouts"][name]
    if "circle" in spec:
        c = spec["circle"]
        return nl.Setup(detector_spots=circle(tuple(c["centre"]), c["radius_m"], c["count"]))
    return nl.Setup(detector_spots=np.asarray(spec["spots"], dtype=float))


def bound_path(cfg: dict, name: str) -> tuple:
    """(family, true parameters) of nlos_cl.tracking.bounds for a path of path_span_s s."""
    spec, span = cfg["paths"][name], cfg["path_span_s"]
    if "line" in spec:
        (x0, y0), (x1, y1) = spec["line"]["start"], spec["line"]["stop"]
        return bounds.line, (x0, y0, (x1 - x0) / span, (y1 - y0) / span)
    c = spec["circle"]
    a0, a1 = (math.radians(a) for a in c["phase_deg"])
    return bounds.circle, (*c["centre"], c["radius_m"], a0, (a1 - a0) / span)


def trajectory(cfg: dict, name: str) -> Trajectory:
    """The walker's path: `waypoints` points of the bound's path on z = 0, lines between."""
    family, params = bound_path(cfg, name)
    n = cfg["paths"][name]["waypoints"]
    t = np.linspace(0, cfg["path_span_s"], n)
    return Trajectory(t, np.column_stack([family(params, t), np.zeros(n)]))
