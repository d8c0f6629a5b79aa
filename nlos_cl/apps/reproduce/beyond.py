"""`nlos-cl reproduce beyond`: the paper's estimator (the argmax) against the model-based one on
scenes the paper does not cover: its 5 x 5 grid, extended targets, other wall-spot layouts (a
32 x 32 SPAD patch among them), targets off z = 0, two targets, photon counts, and how often
the model's 95 % region holds the truth. The cases live in beyond.yaml (none in code); the
report (docs/beyond-the-paper.md) is written by beyond_report from this run's numbers only.

Not part of `reproduce all` (which re-runs the paper and writes paper-results.md): run it on
its own; `--quick` is the small CI setting (tests/test_reproduce_beyond.py)."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

import nlos_cl as nl
from nlos_cl import plotting

from . import beyond_cases as bc
from .beyond_report import coverage_rows, goal_rows, summarise
from .common import Result, Settings

NAME = "beyond"
TITLE = "Beyond the paper: the paper's argmax against the model-based estimator"


def _fmt(p) -> str:
    return "(" + ", ".join(f"{v:g}" for v in p) + ")"


def _entry(section, case, rows, measures=("err3d",), note="", value="") -> dict:
    return {"section": section, "case": case, "rows": rows, "measures": measures, "note": note,
            "value": value}


def _trials(section, case, lay, s, targets, grid, seeds, *, seed0=0, noise=None, k=1,
            model_lay=None) -> list:
    """Simulate once, then both estimators on every seed: CSV rows (one per truth)."""
    clean = bc.simulate(lay, s, targets)
    model_clean = bc.simulate(model_lay, s, targets) if model_lay else None
    truths = np.asarray([t[1] for t in targets], float)
    rows = []
    for seed in range(seed0, seed0 + seeds):
        frame = bc.run_frame(clean, seed, lay, grid, s, k, noise, model_clean, model_lay)
        rows += bc.frame_rows(section, case, lay, seed, frame, truths)
    return rows


def grid_section(cfg, s, key="grid") -> list:
    sec, size = cfg[key], cfg["paper_target"]["size"]
    out = []
    for name in sec["layouts"]:
        lay = bc.layout(cfg, name)
        case, rows = f"{len(sec['x'])} x {len(sec['y'])} grid, {lay.label}", []
        for x in sec["x"]:
            for y in sec["y"]:
                rows += _trials(key, case, lay, s, [(size, (float(x), float(y), 0.0))], s.grid(),
                                s.seeds)
        out.append(_entry(key, case, rows))
    return out


def extended_section(cfg, s) -> list:
    sec, out = cfg["extended"], []
    for name in sec["layouts"]:
        lay = bc.layout(cfg, name)
        for t in sec["targets"]:
            pos, normal = t.get("position", sec["position"]), t.get("normal", (-1.0, 0.0, 0.0))
            case = (f"{t['size'][0]:g} x {t['size'][1]:g} m at {_fmt(pos)}"
                    + (f", normal {_fmt(normal)}" if "normal" in t else "") + f", {lay.label}")
            rows = _trials("extended", case, lay, s, [(t["size"], pos, normal)], s.grid(), s.seeds)
            out.append(_entry("extended", case, rows))
    return out


def spad_section(cfg, s) -> list:
    sec, size = cfg["spad"], cfg["paper_target"]["size"]
    lay = bc.layout(cfg, sec["layout"])
    model_lay = bc.layout(cfg, sec["model_layout"])
    model_lay = None if model_lay.name == lay.name else model_lay
    case, rows = f"{lay.label}, {len(sec['positions'])} position(s)", []
    for pos in sec["positions"]:
        rows += _trials("spad", case, lay, s, [(size, pos)], s.grid(), s.seeds,
                        model_lay=model_lay)
    note = f"paper: all {len(lay.spots)} spots (log mode); model: " + (
        model_lay.label if model_lay else "the same spots")
    out = [_entry("spad", case, rows, note=note)]
    if sec.get("full_patch_model_attempt") and model_lay is not None:
        case = f"model on all {len(lay.spots)} spots, one frame at {_fmt(sec['positions'][0])}"
        rows = _trials("spad", case, lay, s, [(size, sec["positions"][0])], s.grid(), 1)
        out.append(_entry("spad", case, rows, note="every spot, timed"))
    return out


def height_section(cfg, s) -> list:
    sec, size, out = cfg["height"], cfg["paper_target"]["size"], []
    for name in sec["layouts"]:
        lay = bc.layout(cfg, name)
        seen = lay.height_observable
        grid = bc.search_grid(s, sec["z_range"] if seen else None)
        zs = ", ".join(f"{p[2]:g}" for p in sec["positions"])
        case, rows = f"{lay.label}, z = {zs} m", []
        for pos in sec["positions"]:
            rows += _trials("height", case, lay, s, [(size, pos)], grid, s.seeds)
        if seen:
            note = f"both search z in [{sec['z_range'][0]:g}, {sec['z_range'][1]:g}] m"
            out.append(_entry("height", case, rows, ("dz", "err3d"), note))
        else:
            out.append(_entry("height", case, rows, ("errline",),
                              "height unobservable with collinear spots: both hold z = 0; "
                              "error in what they observe (along the line, distance from it)"))
    return out


def two_section(cfg, s) -> list:
    sec, out = cfg["two"], []
    lay = bc.layout(cfg, sec["layout"])
    for a, b in sec["pairs"]:
        for k in sec["targets"]:
            case = (f"two {sec['size'][0]:g} x {sec['size'][1]:g} m at {_fmt(a)} + {_fmt(b)}, "
                    f"K = {k}, {lay.label}")
            rows = _trials("two", case, lay, s, [(sec["size"], a), (sec["size"], b)], s.grid(),
                           s.seeds, k=k)
            found = ",".join(str(r["found"]) for r in rows if r["target"] == 0)
            out.append(_entry("two", case, rows, note=f"targets found per frame: {found}; "
                              "paper: its one position against each truth"))
    return out


def _counter_for(clean, photons: float) -> nl.PhotonCounter:
    """PhotonCounter (defaults) with its pulse count scaled to `photons` signal photons per
    detector (expected, summed over the record; background excluded)."""
    base, hist = nl.PhotonCounter(), clean.histograms()
    total = base.expected_counts(hist).data.sum(axis=1)
    background = base.expected_counts(hist.with_data(np.zeros_like(hist.data))).data.sum(axis=1)
    signal = float(np.mean(total - background))
    return nl.PhotonCounter(n_pulses=base.n_pulses * photons / signal)


def photon_section(cfg, s) -> list:
    sec, size, out = cfg["photons"], cfg["paper_target"]["size"], []
    lay = bc.layout(cfg, sec["layout"])
    clean = bc.simulate(lay, s, [(size, sec["position"])])
    for photons in sec["signal_photons"]:
        counter, rows = _counter_for(clean, photons), []
        case = f"{photons:g} signal photons / detector at {_fmt(sec['position'])}, {lay.label}"
        for seed in range(s.seeds):
            frame = bc.run_frame(clean, seed, lay, s.grid(), s, noise=counter)
            rows += bc.frame_rows("photons", case, lay, seed, frame, [sec["position"]])
        out.append(_entry("photons", case, rows, value=photons))
    return out


def coverage_section(cfg, s) -> list:
    sec, out = cfg["coverage"], []
    for c in sec["cases"]:
        lay = bc.layout(cfg, c["layout"])
        size = c.get("size", cfg["paper_target"]["size"])
        case = f"{size[0]:g} x {size[1]:g} m at {_fmt(c['position'])}, {lay.label}"
        grid = s.grid() if c["position"][2] == 0 or not lay.height_observable else \
            bc.search_grid(s, cfg["height"]["z_range"])
        rows = _trials("coverage", case, lay, s, [(size, c["position"])], grid,
                       s.seeds * sec["frames_per_seed"], seed0=1000)
        out.append(_entry("coverage", case, rows))
    return out


SECTIONS = (("grid", grid_section), ("extended", extended_section),
            ("layout_grid", lambda cfg, s: grid_section(cfg, s, "layout_grid")),
            ("spad", spad_section), ("height", height_section), ("two", two_section),
            ("photons", photon_section), ("coverage", coverage_section))


def _write_csv(path: Path, rows) -> None:
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def beyond(s: Settings, out: Path, only=None) -> Result:
    """Run every section of beyond.yaml (or those in `only`); frame rows go to beyond.csv (by
    `reproduce.run`), the summary to beyond-summary.csv, the figure to beyond.png."""
    cfg = bc.config(s.quick)
    entries = []
    for key, fn in SECTIONS:
        if only is None or key in only:
            entries += fn(cfg, s)
    summary = [row for e in entries for row in summarise(e)]
    coverage, goals = coverage_rows(entries), goal_rows(summary, entries)
    _write_csv(out / "beyond-summary.csv", summary)
    _write_csv(out / "beyond-coverage.csv", coverage)
    figure = plotting.beyond_figure(summary, out, NAME)
    frames = [r for e in entries for r in e["rows"]]
    return Result(NAME, TITLE, frames, {"summary": summary, "coverage": coverage,
                                        "goals": goals}, [figure])
