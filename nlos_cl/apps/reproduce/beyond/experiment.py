"""`nlos-cl reproduce beyond`: the paper's estimator (the argmax) against the model-based one on
scenes the paper does not cover: its 5 x 5 grid, extended targets, other wall-spot layouts (a
32 x 32 SPAD patch among them), targets off z = 0, two targets, photon counts, and how often
the model's 95 % region holds the truth. The cases live in beyond.yaml (none in code); the
sections below turn them into frames (a case, its seeds), which run as one study through the
sweep engine (sweep; a frame is runs.run); the report
(docs/results/beyond/beyond-the-paper.md) is written by report from this run's numbers only.

Not part of `reproduce all` (which re-runs the paper and writes paper-results.md): run it on
its own; `--quick` is the small CI setting (tests/apps/test_reproduce_beyond.py)."""
from __future__ import annotations

from pathlib import Path

from nlos_cl.apps import plotting

from ..common import Result, Settings, write_csv
from . import cases as bc
from .report import cases_table, coverage_rows, goal_rows, summarise
from .sweep import frames as _frames  # a case and its seeds
from .sweep import run_entries

NAME = "beyond"
TITLE = "Beyond the paper: the paper's argmax against the model-based estimator"


def _fmt(p) -> str:
    return "(" + ", ".join(f"{v:g}" for v in p) + ")"


def _entry(section, case, frames, measures=("err3d",), note="", value="") -> dict:
    """One report case: its frames (sweep.frames; rows filled in after the sweep) and
    how it is summarised. `note` may be a function of the rows."""
    return {"section": section, "case": case, "frames": frames, "rows": [],
            "measures": measures, "note": note, "value": value}


def grid_section(cfg, s, key="grid") -> list:
    sec, size = cfg[key], cfg["paper_target"]["size"]
    out = []
    for name in sec["layouts"]:
        lay = bc.layout(cfg, name)
        case = f"{len(sec['x'])} x {len(sec['y'])} grid, {lay.label}"
        frames = [_frames(key, case, lay, [(size, (float(x), float(y), 0.0))], s.seeds)
                  for x in sec["x"] for y in sec["y"]]
        out.append(_entry(key, case, frames))
    return out


def extended_section(cfg, s) -> list:
    sec, out = cfg["extended"], []
    for name in sec["layouts"]:
        lay = bc.layout(cfg, name)
        for t in sec["targets"]:
            pos, normal = t.get("position", sec["position"]), t.get("normal", (-1.0, 0.0, 0.0))
            case = (f"{t['size'][0]:g} x {t['size'][1]:g} m at {_fmt(pos)}"
                    + (f", normal {_fmt(normal)}" if "normal" in t else "") + f", {lay.label}")
            frames = [_frames("extended", case, lay, [(t["size"], pos, normal)], s.seeds)]
            out.append(_entry("extended", case, frames))
    return out


def spad_section(cfg, s) -> list:
    sec, size = cfg["spad"], cfg["paper_target"]["size"]
    lay = bc.layout(cfg, sec["layout"])
    model_lay = bc.layout(cfg, sec["model_layout"])
    model_lay = None if model_lay.name == lay.name else model_lay
    case = f"{lay.label}, {len(sec['positions'])} position(s)"
    frames = [_frames("spad", case, lay, [(size, pos)], s.seeds, model_lay=model_lay)
              for pos in sec["positions"]]
    note = f"paper: all {len(lay.spots)} spots (log mode); model: " + (
        model_lay.label if model_lay else "the same spots")
    out = [_entry("spad", case, frames, note=note)]
    if sec.get("full_patch_model_attempt") and model_lay is not None:
        case = f"model on all {len(lay.spots)} spots, one frame at {_fmt(sec['positions'][0])}"
        frames = [_frames("spad", case, lay, [(size, sec["positions"][0])], 1)]
        out.append(_entry("spad", case, frames, note="every spot, timed"))
    return out


def height_section(cfg, s) -> list:
    sec, size, out = cfg["height"], cfg["paper_target"]["size"], []
    for name in sec["layouts"]:
        lay = bc.layout(cfg, name)
        seen = lay.height_observable
        z_range = sec["z_range"] if seen else None
        zs = ", ".join(f"{p[2]:g}" for p in sec["positions"])
        case = f"{lay.label}, z = {zs} m"
        frames = [_frames("height", case, lay, [(size, pos)], s.seeds, z_range=z_range)
                  for pos in sec["positions"]]
        if seen:
            note = f"both search z in [{sec['z_range'][0]:g}, {sec['z_range'][1]:g}] m"
            out.append(_entry("height", case, frames, ("dz", "err3d"), note))
        else:
            out.append(_entry("height", case, frames, ("errline",),
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
            frames = [_frames("two", case, lay, [(sec["size"], a), (sec["size"], b)], s.seeds,
                              k=k)]
            out.append(_entry("two", case, frames, note=_found_note))
    return out


def _found_note(rows) -> str:
    found = ",".join(str(r["found"]) for r in rows if r["target"] == 0)
    return f"targets found per frame: {found}; paper: its one position against each truth"


def photon_section(cfg, s) -> list:
    sec, size, out = cfg["photons"], cfg["paper_target"]["size"], []
    lay = bc.layout(cfg, sec["layout"])
    for photons in sec["signal_photons"]:  # one scene; the runner scales the counter to it
        case = f"{photons:g} signal photons / detector at {_fmt(sec['position'])}, {lay.label}"
        frames = [_frames("photons", case, lay, [(size, sec["position"])], s.seeds,
                          photons=photons)]
        out.append(_entry("photons", case, frames, value=photons))
    return out


def coverage_section(cfg, s) -> list:
    sec, out = cfg["coverage"], []
    for c in sec["cases"]:
        lay = bc.layout(cfg, c["layout"])
        size = c.get("size", cfg["paper_target"]["size"])
        case = f"{size[0]:g} x {size[1]:g} m at {_fmt(c['position'])}, {lay.label}"
        z_range = None if c["position"][2] == 0 or not lay.height_observable else \
            cfg["height"]["z_range"]
        frames = [_frames("coverage", case, lay, [(size, c["position"])],
                          s.seeds * sec["frames_per_seed"], seed0=1000, z_range=z_range)]
        out.append(_entry("coverage", case, frames))
    return out


SECTIONS = (("grid", grid_section), ("extended", extended_section),
            ("layout_grid", lambda cfg, s: grid_section(cfg, s, "layout_grid")),
            ("spad", spad_section), ("height", height_section), ("two", two_section),
            ("photons", photon_section), ("coverage", coverage_section))


def beyond(s: Settings, out: Path, only=None) -> Result:
    """Run every section of beyond.yaml (or those in `only`) as one sweep study; frame rows go
    to beyond.csv (by `reproduce.run`), the summary to beyond-summary.csv, the figure to
    beyond.png, the sweep's table to OUT/beyond_sweep/."""
    cfg = bc.config(s.quick)
    entries = []
    for key, fn in SECTIONS:
        if only is None or key in only:
            entries += fn(cfg, s)
    run_entries(entries, cfg, s, out)
    summary = [row for e in entries for row in summarise(e)]
    coverage, goals = coverage_rows(entries), goal_rows(summary, entries)
    write_csv(out / "beyond-summary.csv", summary)
    write_csv(out / "beyond-coverage.csv", coverage)
    figure = plotting.beyond_figure(summary, out, NAME)
    frames = [r for e in entries for r in e["rows"]]
    # the targets' checks: --json only ("goals"); the terminal shows the cases table
    return Result(NAME, TITLE, frames, {"summary": summary, "coverage": coverage,
                                        "goals": goals, "markdown": cases_table(summary)},
                  [figure])
