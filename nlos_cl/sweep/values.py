"""The values of a study's axes as a study file writes them: lists, ranges, seeds, scales.
Each is checked where it enters (text, true/false and .inf are no numbers; counts are whole),
so a bad study fails when it is loaded, in one line naming the key."""
from __future__ import annotations

import math

from ..core.errors import require
from ..io.yamlfile import is_number
from .bounds import shown

MAX_AXIS_VALUES = 1_000_000  # one axis's values are held as a tuple while the study is parsed


def axis_values(where: str, spec: dict) -> tuple:
    require(("values" in spec) != ("range" in spec), where, "needs exactly one of values, range",
            "write values: [...] or range: {start, stop, step} / {start, stop, num}")
    if "values" in spec:
        values = spec["values"]
        require(isinstance(values, list) and values, f"{where}.values",
                f"expected a non-empty list, got {shown(values)}", "write e.g. values: [0, 5, 10]")
        require(len(values) <= MAX_AXIS_VALUES, f"{where}.values", f"has {len(values)} values, "
                f"more than {MAX_AXIS_VALUES}", "split the study")
        return tuple(values)
    r = spec["range"]
    require(isinstance(r, dict) and set(r) in ({"start", "stop", "step"}, {"start", "stop", "num"}),
            f"{where}.range", f"expected {{start, stop, step}} or {{start, stop, num}}, got "
            f"{shown(r)}",
            "write e.g. range: {start: 1, stop: 5, step: 1}")
    for key in sorted(set(r) - {"num"}):  # text, true/false and .inf are no range ends
        require(is_number(r[key]), f"{where}.range.{key}", f"expected a finite number, got "
                f"{shown(r[key])}", "write e.g. range: {start: 1, stop: 5, step: 1}")
    start, stop = float(r["start"]), float(r["stop"])
    if "num" in r:
        n = whole_number(f"{where}.range.num", r["num"], 1, MAX_AXIS_VALUES, 5)
        return tuple(start if n == 1 else start + (stop - start) * k / (n - 1) for k in range(n))
    step = float(r["step"])
    require(step > 0 and stop >= start, f"{where}.range", "needs step > 0 and stop >= start",
            "write e.g. {start: 1, stop: 5, step: 1}")
    n = math.floor((stop - start) / step + 1e-9) + 1
    require(n <= MAX_AXIS_VALUES, f"{where}.range", f"makes {n:.3g} values, more than "
            f"{MAX_AXIS_VALUES}", "take a larger step")
    return tuple(round(start + k * step, 12) for k in range(n))


def whole_number(where: str, value, low: int, high: int, example) -> int:
    """An integer in low..high, written as one (2.7 and `true` are refused, not truncated);
    the value is shown bounded (a 100 kB text, an integer of 10^5 digits)."""
    import numpy as np
    ok = isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))
    require(ok and low <= value <= high, where, f"expected a whole number in {low}..{high}, got "
            f"{shown(value)}", f"write e.g. {example}")
    return int(value)


def check_scale(where: str, path: str, values, scale) -> None:
    def number(v):
        return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)

    def ok(node):
        return number(node) or (isinstance(node, list) and node and all(ok(n) for n in node))
    require(path not in ("estimator", "seed", "filter"), f"{where}.scale", f"cannot scale the "
            f"{path} axis", "leave scale out (it is for numeric values: units, spacings)")
    require(all(number(v) for v in values), f"{where}.scale", "needs numeric values",
            "write the axis's values as numbers, or leave scale out")
    require(bool(ok(scale)), f"{where}.scale", "expected a number or (nested) lists of "
            f"numbers, got {shown(scale)}", "write e.g. scale: 1.0e-9, or [[-1, 0, 0], [-2, 0, 0]]")


def scaled(value, scale):
    """What an axis value sets: value x scale, element-wise through nested lists."""
    if scale is None:
        return value
    return [scaled(value, s) for s in scale] if isinstance(scale, list) else value * scale


def seed_values(value) -> tuple:
    if isinstance(value, int) and not isinstance(value, bool):
        return tuple(range(whole_number("seeds", value, 1, MAX_AXIS_VALUES, 10)))
    if isinstance(value, dict):
        require(set(value) == {"start", "count"}, "seeds", f"expected {{start, count}}, got "
                f"{shown(value)}", "write e.g. seeds: {start: 100, count: 10}")
        start = whole_number("seeds.start", value["start"], 0, 2 ** 32, 100)
        count = whole_number("seeds.count", value["count"], 1, MAX_AXIS_VALUES, 10)
        return tuple(range(start, start + count))
    ok = isinstance(value, list) and value and all(
        isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in value)
    require(ok, "seeds", f"expected a count, a list of non-negative integers or {{start, count}},"
            f" got {shown(value)}", "write e.g. seeds: 10")
    require_distinct("seeds", value, "give each seed once (a repeated seed repeats its runs)")
    return tuple(value)


def _same(value):
    """What a value is for a run (1 and 1.0 alike; lists and mappings by their contents)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return ("n", float(value))
    if isinstance(value, (list, tuple)):
        return ("l", tuple(_same(v) for v in value))
    if isinstance(value, dict):
        return ("d", tuple(sorted((repr(k), _same(v)) for k, v in value.items())))
    return (type(value).__name__, repr(value))


def require_distinct(where: str, rows, fix: str) -> None:
    """Each row (an axis's value, or a zip group's values together) once: a repeated one runs
    the same runs twice and counts them twice in the summary."""
    seen: dict = {}
    for k, row in enumerate(rows):
        first = seen.setdefault(_same(row), k)
        require(first == k, where, f"holds {shown(row)} twice (at positions {first} and {k})",
                fix)


def require_separate_paths(axes) -> None:
    """`axes`: (field, path as written, path steps) of every axis. Two axes on one key (or one
    on a key inside another's: targets[0].position and targets[0].position[0]) would overwrite
    each other, and the table would say values the runs did not have."""
    for i, (field, path, steps) in enumerate(axes):
        for other, before, other_steps in axes[:i]:
            n = min(len(steps), len(other_steps))
            require(steps[:n] != other_steps[:n], field, f"sets {shown(path)}, which {other} "
                    f"sets too ({shown(before)})", "vary one key with one axis (zip two axes "
                    "to vary their keys together; `estimators:` and `seeds:` are the estimator's "
                    "and the seed's axes)")


def check_grid(value) -> dict | None:
    """A study's `grid`: {x, y, z: [low, high], step_m}, as locate's --region and --step are
    checked: numbers, and a score map within the kernels' index (2^31 cells) and the memory
    budget (4 bytes a cell), so a step far below what the search can score is refused."""
    if value is None:
        return None
    fix = "write e.g. grid: {x: [0, 6], y: [0.01, 6], step_m: 0.01}, or leave it out"
    require(isinstance(value, dict) and "step_m" in value and all(
        k in ("x", "y", "z", "step_m") for k in value), "grid", "expected {x, y, z, step_m}, "
        f"got {shown(value)}", fix)
    for axis in ("x", "y", "z"):
        ends = value.get(axis, [0, 0])
        require(isinstance(ends, list) and len(ends) == 2 and all(map(is_number, ends)),
                f"grid.{axis}", f"expected [low, high] in metres, got {shown(ends)}", fix)
    step = value["step_m"]
    require(is_number(step) and step > 0, "grid.step_m", f"expected a positive length in "
            f"metres, got {shown(step)}", fix)
    from ..core.grid import Grid
    from ..core.limits import require_memory
    cells = math.prod(max(0.0, (hi - lo) / step) + 1 for lo, hi in
                      (value.get(a, [0, 0]) for a in ("x", "y", "z")))  # inf for 1e-320 steps
    require(cells < 2 ** 31, "grid.step_m", f"makes {cells:.3g} cells at a {step:g} m step, "
            "more than the search's kernels index (2^31)", "take a larger step_m or a smaller "
            "grid")
    require_memory("grid.step_m", 4.0 * cells, f"a score map of {cells:.3g} cells at a "
                   f"{step:g} m step", "take a larger step_m or a smaller grid")
    Grid.from_ranges(**value)  # its own checks: ranges not inverted, y > 0
    return dict(value)
