"""What every experiment shares: settings, the result record, the paper's target, the trial
loop (noise seeds x methods), error statistics, and the data files (the paper's numbers and
our prose) loaded from this package; each experiment's subpackage keeps its own data files,
read with load_data(name, __package__)."""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

import numpy as np
import yaml

import nlos_cl as nl

METHODS = ("filter", "fit", "raw")
PAPER_POSITION = (4.0, 2.0, 0.0)


def load_data(name: str, package: str = __package__) -> dict:
    """A YAML data file of `package` (this one by default; an experiment's subpackage passes
    its own __package__): package data, so it ships in the wheel."""
    return yaml.safe_load(resources.files(package).joinpath(name).read_text("utf-8"))


PAPER: dict = load_data("paper.yaml")  # the paper's numbers, as printed
TEXT: dict = load_data("text.yaml")  # titles, report templates, remarks


def title(name: str) -> str:
    return TEXT["experiments"][name]["title"]


@dataclass(frozen=True)
class Settings:
    """How finely and how often: the full setting, or --quick for CI."""

    seeds: int = 3
    facet_m: float = 0.01
    grid_step_m: float = 0.01
    dt_s: float = 1e-12
    snr_db: float = 10.0
    h_s: float = 0.65e-9
    quick: bool = False
    workers: int | None = 0  # sweep engine for the study figures: 0 this process, None per core

    @classmethod
    def make(cls, quick=False, seeds=None) -> "Settings":
        base = cls(seeds=1, facet_m=0.02, grid_step_m=0.02, quick=True) if quick else cls()
        return replace(base, seeds=seeds) if seeds else base

    def grid(self) -> nl.Grid:
        return nl.Grid.from_ranges(x=(0.0, 6.0), y=(0.01, 6.0), step_m=self.grid_step_m)

    def describe(self) -> str:
        return TEXT["settings"].format(
            seeds=self.seeds, snr_db=self.snr_db, dt_ps=self.dt_s * 1e12,
            facet_cm=self.facet_m * 100, step_cm=self.grid_step_m * 100, h_ns=self.h_s * 1e9)


@dataclass
class Result:
    name: str
    title: str
    rows: list  # table rows (dicts), written as CSV
    summary: dict  # what --json prints
    figures: list = field(default_factory=list)
    seconds: float = 0.0


def paper_target(position=PAPER_POSITION, width=0.3, height=1.6, s: Settings = Settings(),
                 setup=None) -> nl.Scene:
    """The paper's upright rectangle (perpendicular to the x axis, facing the wall side)."""
    mesh = nl.rectangle(width, height, centre=position, normal=(-1.0, 0.0, 0.0), cell_m=s.facet_m)
    return nl.Scene(setup or nl.paper_setup(), nl.Target(mesh), s.facet_m, truth=position)


def simulate_clean(scene: nl.Scene, s: Settings):
    """The noiseless signals of a scene on the device, with the settings' time bins."""
    return nl.simulate(scene, nl.default_time_axis(scene.setup, s.dt_s))


def run_trials(scene: nl.Scene, s: Settings, methods=METHODS, h_values=None):
    """Simulate once; per seed: noise, then locate with each method (and each h for 'filter').
    Returns {method or ('filter', h): [Location per seed]}, and the clean signals."""
    grid = s.grid()
    clean = simulate_clean(scene, s)
    h_values = h_values or [s.h_s]
    out = {}
    for seed in range(s.seeds):
        noisy = nl.add_noise(clean, s.snr_db, seed)
        if "filter" in methods:
            for h in h_values:
                key = "filter" if len(h_values) == 1 else ("filter", h)
                out.setdefault(key, []).append(nl.locate(nl.gauss_filter(noisy, h), grid, estimator="paper"))
        if "fit" in methods:
            out.setdefault("fit", []).append(nl.locate(nl.gauss_fit(noisy)[0], grid, estimator="paper"))
        if "raw" in methods:
            # raw given: the noisy signal scored as it is, as the paper did (nl.locate
            # Gauss-filters signals that look unfiltered only where no raw is given)
            out.setdefault("raw", []).append(nl.locate(noisy, grid, estimator="paper",
                                                       raw=noisy))
    return out, clean


def error_stats(errors) -> dict:
    """Mean, std and max of position errors (m), rounded to 0.1 mm."""
    e = np.asarray(errors, dtype=float)
    return {"mean_m": round(float(e.mean()), 4), "std_m": round(float(e.std()), 4),
            "max_m": round(float(e.max()), 4)}


def stats(locations) -> dict:
    """error_stats over seeds, and the mean located position (x, y), rounded to 1 mm."""
    pos = np.mean([loc.position for loc in locations], axis=0)
    return {**error_stats([loc.error_m for loc in locations]),
            "x": round(float(pos[0]), 3), "y": round(float(pos[1]), 3)}


def flat(method: str, st: dict) -> dict:
    """{'mean_m': ..} -> {'<method>_mean_m': ..}, for a CSV row."""
    return {f"{method}_{k}": v for k, v in st.items()}


def paper_position_row(key, value, st, paper, **extra) -> dict:
    """Our filter's mean position beside the paper's (x, y), and the distance between them."""
    px, py = paper
    return {key: value, "x": st["x"], "y": st["y"], "error_mean_m": st["mean_m"], **extra,
            "paper_x": px, "paper_y": py,
            "distance_to_paper_m": round(math.hypot(st["x"] - px, st["y"] - py), 3)}


def fwhm_ns(t_s, y) -> float:
    """Full width at half maximum of a single-peaked curve, by linear interpolation."""
    i = int(np.argmax(y))
    half = 0.5 * y[i]
    left = np.nonzero(y[:i] < half)[0]
    right = np.nonzero(y[i:] < half)[0]
    if not left.size or not right.size:
        return float("nan")
    a, b = left[-1], i + right[0]
    t_left = np.interp(half, [y[a], y[a + 1]], [t_s[a], t_s[a + 1]])
    t_right = np.interp(half, [y[b], y[b - 1]], [t_s[b], t_s[b - 1]])
    return float((t_right - t_left) * 1e9)


def write_csv(path: Path, rows) -> None:
    """Rows of dicts as a CSV table, the first row's keys as the header."""
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
