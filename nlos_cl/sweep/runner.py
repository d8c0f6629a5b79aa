"""Studies of any function (docs/sweeps.md, "A study of your own function"): `runner` names
a function instead of a scene, its axes are the function's keyword parameters, and each run's
return value is stored as JSON text in the table's `result` column.

    runner: "mypackage.experiment:run_one"   # importable where the runs run (or, from Python,
    axes:                                     #  the function itself)
      - {name: case, values: [0, 1, 2]}
    seeds: 3                                  # optional: a `seed` parameter, fastest
    params: {quick: true}                     # the same keyword arguments for every run

Run i calls `run_one(**params, case=..., seed=...)`. The engine is the same as for scene
studies (batches, Dask, Parquet parts, --resume); runs that differ only in `seed` share a
batch, so a per-process cache of the expensive part (`worker_cache`) serves all their seeds.
"""
from __future__ import annotations

import functools
import importlib
import inspect
import json
import re
import time
from collections import OrderedDict
from dataclasses import dataclass, field

from ..core.errors import InputError, require
from .bounds import key_name, shown
from .registry import is_own, is_registered
from .study import Axis, Study, assignments, axis_group, axis_values, check_scale, seed_values

TOP = {"description", "runner", "axes", "seeds", "params", "batch_size"}
COLUMNS = ("result", "t_run_s", "t_cpu_s")  # a runner study's measured columns, then failure
RESERVED = {"run_id", "failure", *COLUMNS}
MAX_NAME = 200  # characters of a runner's name (it is echoed in errors)
_NAME = re.compile(r"[A-Za-z_][\w.]*:(?!__)[A-Za-z_]\w*(\.(?!__)[A-Za-z_]\w*)*")  # no dunders


@dataclass(frozen=True)
class RunnerStudy(Study):
    """A study whose run is a call of `runner` (no scene: `base` and `settings` are empty)."""

    runner: object = None  # 'package.module:function', or the callable itself
    params: dict = field(default_factory=dict)

    def plan(self) -> dict:
        return {"runner": self.runner, "params": self.params,
                "paths": {a.name: a.name for a in self.axes},
                "scales": {a.name: a.scale for a in self.axes if a.scale is not None}}

    def as_dict(self) -> dict:
        def axis(a):
            scale = {} if a.scale is None else {"scale": a.scale}
            return {"name": a.name, "values": list(a.values), **scale}
        axes = [axis(g[0]) if len(g) == 1 else {"zip": [axis(a) for a in g]}
                for g in self.groups]
        return {"description": self.description, "runner": runner_name(self.runner),
                "axes": axes, "params": self.params, "batch_size": self.batch_size}


def runner_name(runner) -> str:
    """'module:function' of a runner (what study.json and the fingerprint keep)."""
    if isinstance(runner, str):
        return runner
    return f"{runner.__module__}:{getattr(runner, '__qualname__', type(runner).__name__)}"


def allowed(module: str, allow=()) -> bool:
    """Whether a study file may import `module`: nlos_cl's own (whose functions then run only
    when registered: registry.py), or a module the user allowed (`allow`: module names; each
    allows its submodules too)."""
    return is_own(module) or any(module == m or module.startswith(m + ".") for m in allow)


def resolve(runner, allow=()):
    """The function a `runner` value names ('package.module:function', or a callable).

    A study file is data, but a runner is code it runs: `runner: "os:system"` with an axis of
    commands would run each one, and `nlos_cl.sweep.engine:sweep` would run any study. So a
    name resolves only to a function nlos_cl registered as a study runner (registry.runner),
    or to a function of a module in `allow` (nlos-cl sweep --allow-runner MODULE,
    nl.sweep(..., allow_runner=[MODULE])): the user's explicit word that the module is theirs
    to run. The module is checked before it is imported (an import runs its code), and the
    function found must be defined in an allowed module (not `os.system` reached through an
    allowed module's `import os`). A callable passed from Python is the caller's own code."""
    fix = ("write runner: \"package.module:function\", a function the workers can import "
           "(from Python you may pass the function itself)")
    if not isinstance(runner, str):
        require(callable(runner), "runner", f"expected a function, got {shown(runner)}", fix)
        return runner
    require(len(runner) <= MAX_NAME and bool(_NAME.fullmatch(runner)), "runner",
            f"expected 'package.module:function' (at most {MAX_NAME} characters), got "
            f"{shown(runner)}", fix)
    module, _, name = runner.partition(":")
    allow = (allow,) if isinstance(allow, str) else tuple(allow or ())
    require(allowed(module, allow), f"runner {runner!r}", f"cannot import {module!r} from a "
            "study file: a runner is code the study runs, and only nlos_cl's registered "
            "runners run without your word", f"if you trust {module!r}, allow it: nlos-cl "
            f"sweep --allow-runner {module} (nl.sweep(..., allow_runner=[{module!r}]))")
    obj = _import(runner)
    home = getattr(inspect.unwrap(obj), "__module__", None) or ""
    require(allowed(home, allow), f"runner {runner!r}", f"is {home or 'a builtin'}'s "
            f"{getattr(obj, '__name__', name)}, not a function of {module!r}",
            "name the function where it is defined (and allow that module only if you trust it)")
    if is_own(home) or is_own(module):  # nlos_cl's: registered runners only, allowed or not
        require(is_registered(obj), f"runner {runner!r}", "is not a registered study runner "
                "(of nlos_cl's functions a study may name only those marked @runner in "
                "nlos_cl.sweep.registry)", "name one, e.g. nlos_cl.sweep.examples:paper_target, "
                "or a function of your own module with --allow-runner MODULE")
    return obj


def _import(runner: str):
    """The callable `runner` names (already allowed: see resolve), imported."""
    module, _, name = runner.partition(":")
    try:
        obj = importlib.import_module(module)
    except ImportError as exc:
        raise InputError(f"runner {runner!r}: cannot import {module!r} ({shown(str(exc))}). "
                         "Fix: install the module where the study runs, or correct the name"
                         ) from None
    for part in name.split("."):
        # through nlos_cl, only modules and classes: an object's property is code that runs
        inside = inspect.ismodule(obj) or inspect.isclass(obj) or not is_own(module)
        try:
            obj = getattr(obj, part) if inside else None
        except Exception:  # noqa: BLE001 - AttributeError, or a property that raised
            obj = None
        require(obj is not None, f"runner {runner!r}", f"{module!r} has no {name!r}",
                "check the function's name after the colon")
    require(callable(obj) and not inspect.ismodule(obj), f"runner {runner!r}",
            f"is not callable (a {type(obj).__name__})", "name a function")
    return obj


def _check_call(fn, runner, names) -> None:
    """The function must accept every axis and params name (found at load, not per run)."""
    try:
        signature = inspect.signature(fn)
    except (TypeError, ValueError):  # some builtins: nothing to check
        return
    try:
        signature.bind(**dict.fromkeys(names))
    except TypeError as exc:
        raise InputError(f"runner {runner_name(runner)!r}: cannot be called with the study's "
                         f"parameters {shown(sorted(names))} ({shown(str(exc))}). Fix: rename "
                         "the axes or params to the function's parameters, or add them to the "
                         "function") from None


def _axis(where: str, spec) -> Axis:
    require(isinstance(spec, dict) and "name" in spec and "path" not in spec, where,
            f"expected {{name, values}} or {{name, range}}, got {shown(spec)}", "a runner study's "
            "axes are its function's parameters: write e.g. {name: case, values: [0, 1]}")
    unknown = sorted(set(spec) - {"name", "values", "range", "scale"}, key=str)
    require(not unknown, f"{where}.{key_name(unknown[0]) if unknown else ''}", "is not a known key",
            "use name, values, range or scale")
    name = spec["name"]
    require(isinstance(name, str) and name.isidentifier() and name not in RESERVED
            and len(name) <= MAX_NAME,
            f"{where}.name", f"expected a parameter name, got {shown(name)}",
            f"write a Python identifier other than {sorted(RESERVED)}")
    values = axis_values(where, spec)
    if spec.get("scale") is not None:
        check_scale(where, name, values, spec["scale"])
    return Axis(name, name, values, spec.get("scale"))


def load_runner_study(raw: dict, base_dir=None, allow_runner=()) -> RunnerStudy:
    """A RunnerStudy from a study mapping with a `runner` (checked: allowed (see resolve),
    importable, callable, taking every axis and params name)."""
    unknown = sorted(set(raw) - TOP, key=str)
    require(not unknown, f"study.{key_name(unknown[0]) if unknown else ''}", "is not a known "
            "key of a runner study", f"use one of {sorted(TOP)} (scene studies: no runner)")
    fn = resolve(raw["runner"], allow_runner)
    axes = raw.get("axes") or []
    require(isinstance(axes, list), "axes", "expected a list", "write axes: [{name, values}]")
    groups = [axis_group(i, spec, _axis) for i, spec in enumerate(axes)]
    if "seeds" in raw:
        groups.append((Axis("seed", "seed", seed_values(raw["seeds"])),))
    require(bool(groups), "axes", "a runner study needs at least one axis or seeds",
            "write axes: [{name: case, values: [0, 1]}] or seeds: 10")
    params = raw.get("params") or {}
    require(isinstance(params, dict) and all(isinstance(k, str) for k in params), "params",
            f"expected a mapping of keyword arguments, got {shown(params)}", "write params: {a: 1}")
    names = [a.name for g in groups for a in g] + list(params)
    dup = sorted({n for n in names if names.count(n) > 1})
    require(not dup, f"axes/params: name {shown(dup[0] if dup else '')}", "is used twice",
            "give each parameter one source: an axis, seeds, or params")
    _check_call(fn, raw["runner"], names)
    batch = raw.get("batch_size")
    require(batch is None or (isinstance(batch, int) and batch >= 1), "batch_size",
            f"must be a positive integer, got {shown(batch)}", "write e.g. batch_size: 16")
    return RunnerStudy(str(raw.get("description", "")), {}, tuple(groups), {}, batch,
                       raw["runner"], dict(params))


@functools.lru_cache(maxsize=16)
def _named(runner: str):
    """On a worker: the study was checked when it was loaded (resolve), so only import."""
    return _import(runner)


def _plain(value):
    """JSON for NumPy scalars and arrays in a result (anything else is the runner's error)."""
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"a result holds a {type(value).__name__}, which JSON cannot write")


def run_calls(plan: dict, runs) -> list[dict]:
    """Call the runner for every (run_id, values) of `runs`: one row per run with its result
    as JSON text (None where it raised), its wall and CPU time, and `failure`."""
    fn = _named(plan["runner"]) if isinstance(plan["runner"], str) else plan["runner"]
    rows = []
    for run_id, values in runs:
        start, cpu = time.perf_counter(), time.process_time()
        try:
            value = fn(**plan["params"], **assignments(plan, values))
            result, failure = json.dumps(value, default=_plain), ""
        except Exception as exc:  # noqa: BLE001 - one bad run must not end the study
            result, failure = None, f"{type(exc).__name__}: {exc}"[:500]
        rows.append({"run_id": run_id, "result": result, "t_run_s": time.perf_counter() - start,
                     "t_cpu_s": time.process_time() - cpu, "failure": failure})
    return rows


def worker_cache(keep: int = 3):
    """Decorator: keep the values of the last `keep` calls in this process, keyed by the
    arguments' JSON (mappings and lists allowed). For the expensive part that a study's runs
    share (a clean simulation used by every seed): each worker process has its own, so the
    function must give the same value fresh or cached (deterministic)."""
    def wrap(fn):
        store: OrderedDict = OrderedDict()

        @functools.wraps(fn)
        def cached(*args, **kwargs):
            key = json.dumps([args, kwargs], sort_keys=True, default=repr)
            if key in store:
                store.move_to_end(key)
                return store[key]
            store[key] = value = fn(*args, **kwargs)
            while len(store) > keep:
                store.popitem(last=False)
            return value
        cached.cache_clear = store.clear
        return cached
    return wrap
