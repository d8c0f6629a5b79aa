"""The command line's argument types: a parser whose errors are one line, a help formatter
that states defaults, and number types with the ranges the API checks (apps/cli.py)."""
from __future__ import annotations

import argparse
import math
import re


class Parser(argparse.ArgumentParser):
    """argparse, but a bad argument is one line on stderr (field, problem, fix) and exit 2,
    and `-1e300` is a (negative) number, not an option (argparse's own matcher wants no
    exponent, so `--snr-db -1e300` was "expected one argument")."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(
            r"^-(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?$")

    def error(self, message):
        self.exit(2, f"{self.prog}: {message}\n")


class Defaults(argparse.HelpFormatter):
    """--help says each option's default, where it has one and its help does not say it."""

    def _get_help_string(self, action):
        text = action.help or ""
        default = action.default
        if (default in (None, False, "", argparse.SUPPRESS) or "default" in text
                or not action.option_strings):
            return text
        return f"{text} (default: {default})" if text else f"default: {default}"


def number(field: str, fix: str, *, positive=False, minimum=None, integer=False, maximum=None):
    """An argparse type: a finite number (int if `integer`) <= maximum, as the API checks it."""
    def parse(text):
        try:
            value = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{field}: {text!r} is not "
                                             f"{'an integer' if integer else 'a number'}. "
                                             f"Fix: {fix}") from None
        bad = (not math.isfinite(value) or (positive and value <= 0)
               or (minimum is not None and value < minimum))
        if bad:
            need = ("positive" if positive else f">= {minimum}" if minimum is not None
                    else "finite")
            raise argparse.ArgumentTypeError(f"{field}: must be {need}, got {text}. Fix: {fix}")
        if maximum is not None and value > maximum:
            raise argparse.ArgumentTypeError(f"{field}: must be at most {maximum:g}, got {text}. "
                                             f"Fix: {fix}")
        return value
    return parse


# Ranges no later check sees (frame and target counts: core/limits.py): frame k is at k / fps,
# [1e-6, 1e6] Hz; no hidden object accelerates over 1000 g (1e300 overflows the tracker).
MIN_FPS, MAX_FPS, MAX_ACCEL = 1e-6, 1e6, 1e4
COORD = number("position", "pass finite coordinates in metres")
SEED = number("seed", "pass e.g. 0", minimum=0, integer=True)
H_NS = number("h_s", "pass the window in ns, e.g. 0.65", positive=True)


def reflectance(text: str):
    """--reflectance MODEL[:KEY=VALUE,...], e.g. retroreflective:retro=0.7,width_rad=0.005:
    the scene files' `reflectance:` mapping (physics.reflectance.from_spec) on one line."""
    from ..core.errors import InputError
    from ..physics.reflectance import from_spec
    name, _, rest = text.partition(":")
    spec = {"model": name.strip().lower()}
    try:
        for item in filter(None, (s.strip() for s in rest.split(","))):
            key, sep, value = (part.strip() for part in item.partition("="))
            if not sep:
                raise ValueError(f"{item!r} is not KEY=VALUE")
            if key in spec:
                raise ValueError(f"{key} is given twice")
            try:
                spec[key] = float(value)
            except ValueError:
                raise ValueError(f"{key}={value!r} is not a number") from None
        return from_spec(spec)
    except (ValueError, TypeError, InputError) as exc:
        problem = str(exc).splitlines()[0].split(". Fix: ")[0]  # the CLI's own fix below
        raise argparse.ArgumentTypeError(
            f"reflectance: {text!r}: {problem}. Fix: pass e.g. "
            "retroreflective:retro=0.7,width_rad=0.005,diffuse=0.2 or "
            "ggx:specular=0.5,roughness=0.3") from None


# How the library's errors name its options on the command line (its `names=` arguments).
OPTION_FLAGS = {"region": "--region", "step_m": "--step", "estimator": "--estimator",
                "targets": "--targets", "reflectance": "--reflectance", "accel": "--accel",
                "steady_accel": "--steady-accel", "motion": "--motion",
                "background": "--background"}
