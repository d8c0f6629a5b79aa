"""A study: a base scene, the axes that vary it, and the runs they make (docs/sweeps.md).

Schema (YAML or dict; every key but `scene` optional)::

    scene: docs/scenes/two_targets.yaml   # a scene file (relative to the study) or a scene dict
    axes:                                 # crossed in this order (the last varies fastest)
      - {path: noise.snr_db, values: [0, 5, 10, 20]}
      - {path: targets[0].position[0], name: x, range: {start: 1, stop: 5, step: 1}}
      - {path: h_s, name: h_ns, values: [0.1, 0.65], scale: 1.0e-9}   # sets value x scale
      - zip:                              # zipped: these advance together
          - {path: h_s, values: [0.3e-9, 0.65e-9]}
          - {path: setup.pulse.fwhm_s, range: {start: 35e-12, stop: 70e-12, num: 2}}
    estimators: [paper, model]            # the `estimator` axis, crossed after `axes`
    seeds: 10                             # the noise seeds 0..9 (or a list, or {start, count})
    h_s: 0.65e-9                          # Gauss filter window (an axis may vary `h_s`)
    filter: gauss                         # gauss | gauss_fit | none (an axis may vary it)
    grid: {x: [0, 6], y: [0.01, 6], z: [0, 0], step_m: 0.01}   # default: localization.region.default_region
    record: [position, error, covariance, timings, photons]
    batch_size: 16                        # runs per Dask task (default: from the study's size)

A path addresses a scene-file key (`noise.snr_db`, `setup.detector_spots`,
`targets[0].position[1]`) or one of the run's own settings (`estimator`, `seed`, `h_s`,
`filter`). With `scale` an axis sets value x scale (element-wise through nested lists; the
column keeps the value): units, or one number setting a vector (a detector spacing).
Run i's values are the i-th element of the axes' cross product (seed fastest):
`run_id` is stable for a given study.
"""
from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

from ..core.errors import InputError, require
from ..localization.estimators import estimator_names
from ..io.yamlfile import is_number
from .bounds import bounded, key_name, shown
from .sources import scene as study_scene
from .values import (MAX_AXIS_VALUES, axis_values, check_grid, check_scale, require_distinct,
                     require_separate_paths, scaled, seed_values, whole_number)

TOP = {"description", "scene", "axes", "estimators", "seeds", "h_s", "filter", "grid", "record",
       "batch_size"}
SPECIAL = {"estimator", "seed", "h_s", "filter"}  # not scene keys: the run's own settings
RECORDS = ("position", "error", "covariance", "timings", "photons")
FILTERS = ("gauss", "gauss_fit", "none")
RECORD_COLUMNS = {  # what each `record` entry adds to the table (runs.py fills them)
    "position": ("x_m", "y_m", "z_m", "truth_x_m", "truth_y_m", "truth_z_m"),
    "error": ("error_m",),
    "covariance": ("cov_xx_m2", "cov_xy_m2", "cov_xz_m2", "cov_yy_m2", "cov_yz_m2", "cov_zz_m2"),
    "timings": ("t_simulate_s", "t_noise_s", "t_filter_s", "t_locate_s", "t_run_s", "t_cpu_s"),
    "photons": ("photons", "signal_photons"),
}
SUMMARY_COLUMNS = ("error_mean_m", "error_std_m", "error_max_m", "runs", "t_run_mean_s")
# an axis is a column of the table and of summary.csv: it must not take a result's name
RESERVED = {"run_id", "failure", *SUMMARY_COLUMNS, *(c for cs in RECORD_COLUMNS.values()
                                                      for c in cs)}
MAX_KEY_PATH = 200  # characters of an axis's path (a column name, echoed in errors)
_STEP = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)|\[(\d+)\]|\.")


@dataclass(frozen=True)
class Axis:
    """One varied key: its column name, the path it sets, and its values in order."""

    name: str
    path: str
    values: tuple
    scale: object = None  # the value set is value x scale (scaled); the column keeps the value


@dataclass(frozen=True)
class Study:
    """A parsed study: the base scene dict, the axis groups (zipped inside, crossed between)
    and the run settings. `runs()` lists every run's values; `plan()` is what workers get."""

    description: str
    base: dict
    groups: tuple  # of tuples of Axis (a zip group; a plain axis is a group of one)
    settings: dict  # h_s, filter, grid, record
    batch_size: int | None

    @property
    def axes(self) -> tuple:
        return tuple(a for g in self.groups for a in g)

    @property
    def n_runs(self) -> int:
        return math.prod(len(g[0].values) for g in self.groups)

    def runs(self):
        """(run_id, {axis name: value}) for every run, in run_id order."""
        names = [[a.name for a in g] for g in self.groups]
        rows = [list(zip(*(a.values for a in g))) for g in self.groups]
        for run_id, combo in enumerate(itertools.product(*rows)):
            yield run_id, {n: v for ns, vs in zip(names, combo) for n, v in zip(ns, vs)}

    def plan(self) -> dict:
        """Everything a worker needs, as plain data (cheap to send)."""
        return {"base": self.base, "paths": {a.name: a.path for a in self.axes},
                "scales": {a.name: a.scale for a in self.axes if a.scale is not None},
                **self.settings}

    def as_dict(self) -> dict:
        """The study written out in full (scene inline, ranges expanded): what --resume checks."""
        def axis(a):
            scale = {} if a.scale is None else {"scale": a.scale}
            return {"name": a.name, "path": a.path, "values": list(a.values), **scale}
        *groups, estimators, seeds = self.groups
        axes = [axis(g[0]) if len(g) == 1 else {"zip": [axis(a) for a in g]} for g in groups]
        return {"description": self.description, "scene": self.base, "axes": axes,
                "estimators": list(estimators[0].values), "seeds": list(seeds[0].values),
                **self.settings, "batch_size": self.batch_size}

    def fingerprint(self) -> str:
        text = json.dumps({k: v for k, v in self.as_dict().items() if k != "batch_size"},
                          sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def parse_path(path) -> list:
    """'targets[0].position[1]' -> ['targets', 0, 'position', 1]."""
    require(isinstance(path, str) and 0 < len(path) <= MAX_KEY_PATH, "axes[].path",
            f"expected a key path (at most {MAX_KEY_PATH} characters), got {shown(path)}",
            "write e.g. noise.snr_db or targets[0].position[0]")
    steps, pos = [], 0
    while pos < len(path):
        m = _STEP.match(path, pos)
        require(m is not None and m.end() > pos, f"axes[].path {shown(path)}",
                f"cannot read it at character {pos}", "write keys with dots, indices as [0]")
        if m.group(1):
            steps.append(m.group(1))
        elif m.group(2):
            steps.append(int(m.group(2)))
        pos = m.end()
    require(bool(steps), f"axes[].path {shown(path)}", "is empty", "write e.g. noise.snr_db")
    return steps


def substitute(base: dict, assignments) -> dict:
    """A copy of the scene dict `base` with each (path, value) set; dicts on the way are made
    when missing, list elements must exist."""
    scene = copy.deepcopy(base)
    for path, value in assignments:
        steps, node = parse_path(path), scene
        for i, (step, nxt) in enumerate(zip(steps, steps[1:] + [None])):
            where = _where(steps[:i + 1])
            if isinstance(step, int):
                require(isinstance(node, list) and step < len(node), f"scene {where}",
                        "does not exist in the base scene", "write the whole list in the base "
                        "scene, so the axis can set one element")
            else:
                require(isinstance(node, dict), f"scene {where}", "is not under a mapping",
                        "check the path against docs/scene-files.md")
            if nxt is None:
                node[step] = copy.deepcopy(value)
            else:  # a missing mapping on the way is made
                node = node.setdefault(step, {}) if isinstance(step, str) else node[step]
    return scene


def _where(steps) -> str:
    return "".join(f"[{s}]" if isinstance(s, int) else (f".{s}" if i else s)
                   for i, s in enumerate(steps))


def _axis(where: str, spec) -> Axis:
    require(isinstance(spec, dict) and "path" in spec, where, f"expected {{path, values}} or "
            f"{{path, range}}, got {shown(spec)}", "write e.g. {path: noise.snr_db, values: "
            "[0, 10]}")
    unknown = sorted(set(spec) - {"path", "name", "values", "range", "scale"}, key=str)
    require(not unknown, f"{where}.{key_name(unknown[0]) if unknown else ''}", "is not a known key",
            "use path, name, values, range or scale")
    parse_path(spec["path"])
    values = axis_values(where, spec)
    path = spec["path"]
    if path in ("estimator", "filter"):
        allowed = estimator_names() if path == "estimator" else FILTERS
        bad = [v for v in values if v not in allowed]
        require(not bad, f"{where}.values", f"unknown {path} {shown(bad[0] if bad else '')}",
                f"use {list(allowed)}")
    scale = spec.get("scale")
    if scale is not None:
        check_scale(where, path, values, scale)
    name = spec.get("name", path)
    require(isinstance(name, str) and name.strip() != "" and len(name) <= MAX_KEY_PATH,
            f"{where}.name", f"expected a column name (at most {MAX_KEY_PATH} characters), got "
            f"{shown(name)}", "write e.g. name: snr_db")
    require(name not in RESERVED, f"{where}.name", f"{shown(name)} is a column of the results "
            f"table, reserved: {sorted(RESERVED)}", "give the axis another name: (e.g. "
            f"name: {name}_axis)")
    return Axis(name, path, values, scale)


def assignments(plan: dict, values: dict) -> dict:
    """{path: the value it is set to} for one run (scaled where the axis has a scale)."""
    scales = plan.get("scales", {})
    return {plan["paths"][n]: scaled(v, scales.get(n)) for n, v in values.items()}


def axis_group(i: int, spec, axis=_axis) -> tuple:  # axis: runner studies parse their own
    if isinstance(spec, dict) and set(spec) == {"zip"}:
        require(isinstance(spec["zip"], list) and spec["zip"], f"axes[{i}].zip",
                "expected a list of axes", "write zip: [{path: .., values: ..}, ...]")
        group = tuple(axis(f"axes[{i}].zip[{j}]", s) for j, s in enumerate(spec["zip"]))
        lengths = {len(a.values) for a in group}
        require(len(lengths) == 1, f"axes[{i}].zip", f"zipped axes differ in length "
                f"({sorted(lengths)})", "give every zipped axis the same number of values")
        require_distinct(f"axes[{i}].zip", list(zip(*(a.values for a in group))), "give each "
                         "combination of the zipped values once")
        return group
    group = (axis(f"axes[{i}]", spec),)
    field = "range" if isinstance(spec, dict) and "range" in spec else "values"
    require_distinct(f"axes[{i}].{field}", group[0].values, "give each value once" + (
        " (the range's step is below its 1e-12 rounding)" if field == "range" else ""))
    return group


def _settings(raw: dict) -> dict:
    record = raw.get("record", list(RECORDS))
    require(isinstance(record, list) and all(r in RECORDS for r in record), "record",
            f"expected a list from {list(RECORDS)}, got {shown(record)}",
            f"write e.g. {list(RECORDS)}")
    h_s = raw.get("h_s", 0.65e-9)
    require(is_number(h_s) and 0 < h_s <= 1e-3, "h_s", f"must be a positive time in "
            f"seconds (at most 1 ms), got {shown(h_s)}", "write e.g. 0.65e-9")
    filt = raw.get("filter", "gauss")
    require(filt in FILTERS, "filter", f"unknown filter {shown(filt)}",
            f"use one of {list(FILTERS)}")
    return {"h_s": float(h_s), "filter": filt, "grid": check_grid(raw.get("grid")),
            "record": [r for r in RECORDS if r in record]}


def load_scene_study(raw, base_dir: Path) -> Study:
    """A scene study (the file format above) from its dict."""
    require(isinstance(raw, dict) and "scene" in raw, "study", "needs a `scene` (or a `runner`)",
            "write scene: a scene file path, or the scene's keys inline")
    unknown = sorted(set(raw) - TOP, key=str)
    require(not unknown, f"study.{key_name(unknown[0]) if unknown else ''}", "is not a known key",
            f"use one of {sorted(TOP)}")
    axes = raw.get("axes") or []
    require(isinstance(axes, list), "axes", "expected a list", "write axes: [{path, values}]")
    groups = [axis_group(i, spec) for i, spec in enumerate(axes)]
    estimators = raw.get("estimators", ["paper"])
    require(isinstance(estimators, list) and estimators, "estimators", f"expected a list, got "
            f"{shown(estimators)}", f"write e.g. estimators: [paper] (of {estimator_names()})")
    groups.append((Axis("estimator", "estimator", tuple(estimators)),))
    _axis("estimators", {"path": "estimator", "values": list(groups[-1][0].values)})
    require_distinct("estimators", estimators, "name each estimator once")
    groups.append((Axis("seed", "seed", seed_values(raw.get("seeds", 1))),))
    require_separate_paths([(w + ".path" if w.startswith("axes") else w, a.path,
                             parse_path(a.path)) for w, a in _placed(axes, groups)])
    names = [a.name for g in groups for a in g]
    dup = sorted({n for n in names if names.count(n) > 1})
    require(not dup, f"axes: name {shown(dup[0] if dup else '')}", "is used twice",
            "give one of them another `name:` (estimator and seed are taken)")
    batch = raw.get("batch_size")
    if batch is not None:
        batch = whole_number("batch_size", batch, 1, MAX_AXIS_VALUES, 16)
    return Study(str(raw.get("description", "")), study_scene(raw["scene"], base_dir), tuple(groups),
                 _settings(raw), batch)


def _placed(specs, groups) -> list:
    """(where the study wrote it, Axis) for every axis of `groups` (the axes, then the
    estimators' and the seeds' groups)."""
    wheres = [[f"axes[{i}].zip[{j}]" for j in range(len(g))] if len(g) > 1 or (
        isinstance(spec, dict) and "zip" in spec) else [f"axes[{i}]"]
        for i, (spec, g) in enumerate(zip(specs, groups))] + [["estimators"], ["seeds"]]
    return [(w, a) for ws, g in zip(wheres, groups) for w, a in zip(ws, g)]


def scene_of(plan: dict, values: dict) -> dict:
    """The scene dict of one run: the base with the run's scene-key axes substituted."""
    return substitute(plan["base"], [(p, v) for p, v in assignments(plan, values).items()
                                     if p not in SPECIAL])


def check_scenes(study: Study) -> int:
    """Load the scene of every axis value once (the other axes at their first values), so a bad
    value fails here, before any work is sent. Returns the number of scenes checked."""
    from ..io.scenefile import load_scene
    plan, first = study.plan(), {a.name: a.values[0] for a in study.axes}
    seen = set()
    for group in study.groups:
        for k in range(len(group[0].values)):
            values = {**first, **{a.name: a.values[k] for a in group}}
            scene = scene_of(plan, values)
            key = json.dumps(scene, sort_keys=True, default=str)
            if key in seen:
                continue
            seen.add(key)
            try:
                load_scene(scene)
            except InputError as exc:
                values = {a.name: a.values[k] for a in group}
                raise InputError(f"study axes {shown(values, 160)}: {bounded(exc)}") from None
    return len(seen)
