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
    return tuple(value)
