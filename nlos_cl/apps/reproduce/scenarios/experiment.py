"""`nlos-cl reproduce scenarios`: first-use scenes drawn at random (draws; the ranges in
scenarios.yaml), each written as a scene file, simulated with `nlos-cl simulate` and answered
by `nlos-cl locate F.h5 --json` or `nlos-cl track SEQ.h5 --json` with no option (run), scored
against its truths (score); the page and its tables from the rows alone (report).

Writes OUT/scenarios.csv (every draw, by `reproduce.run`), OUT/scenarios-summary.csv and
OUT/scenarios.md (with --doc, that page there too). `--draws N` draws N scenes in all (default
scenarios.yaml's 200), family by family in turn. While it runs, each finished row is appended
to OUT/scenarios-progress.jsonl (removed at the end: a run cut short keeps its rows).
Re-run one draw alone: `rerun(17, folder)` (its scene file and capture are left in folder)."""
from __future__ import annotations

import json
import math
import os
import tempfile
import time
import traceback
from pathlib import Path

from tqdm import tqdm

import nlos_cl as nl
from nlos_cl.core.errors import require

from ..common import Result, Settings, write_csv
from ..draws.experiment import uniform
from . import draws as dr
from . import report

NAME = "scenarios"
TITLE = "Scenarios: first-use scenes through the command line, with no option"
FAMILIES = {
    "clutter": "a sequence (`nlos-cl simulate --frames`, then `nlos-cl track`): one or two "
               "movers (plates or people) walking past one or two static boxes or cabinets",
    "multi": "1-3 targets (plates, boxes, people), the number unknown to the command",
    "shapes": "one plate (0.2-1.2 m wide, up to 1.8 m tall), box or person (a capsule mesh "
              "file, 1.5-1.9 m tall)",
    "records": "a gated record (opening shortly before the first return) or a short one "
               "(closing shortly after the last)",
    "bins": "photon counts in TDC bins of 16 ps to 1.5 ns (log-uniform)",
    "counts": "photon counts, 1e5-1e9 pulses, ambient and dark rates drawn (log-uniform)",
    "walls": "the capture rewritten in any rigid frame (tilted, moved, both), or its wall "
             "points jittered by up to 3 cm off the plane and simulated where they are",
    "occluders": "a plate between the wall and the target (both are objects to find)"}


def scenarios(s: Settings, out: Path, draws: int | None = None,
              master_seed: int | None = None, only=None) -> Result:
    """Run `draws` scenarios (default scenarios.yaml's), write the summary CSV and the page;
    `only` (family names) keeps the draws of those families among the first `draws`, the
    same draws a full run makes (a family measured alone)."""
    cfg = dr.config()
    count = draws or cfg["draws"]
    require(isinstance(count, int) and count >= 1, "--draws", f"must be a positive whole "
            f"number, got {count!r}", "pass e.g. --draws 200")
    for f in only or ():
        require(f in cfg["families"], "--only", f"{f!r} is not a scenario family",
                "name some of " + ", ".join(cfg["families"]))
    seed = cfg["master_seed"] if master_seed is None else int(master_seed)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    indices = [i for i in range(count) if not only or dr.family_of(i, cfg) in only]
    rows, broken = run_rows(indices, seed, cfg, out / f"{NAME}-progress.jsonl")
    seconds = time.perf_counter() - start
    families = [f for f in cfg["families"] if not only or f in only]
    summ = report.summary(rows, families)
    write_csv(out / f"{NAME}-summary.csv", summ)
    options = (f" --draws {count}" if draws else "") + (" --only " + " ".join(only)
                                                        if only else "")
    text = page(rows, broken, summ, cfg, options, seconds, seed)
    from ....io.safe_write import write_text
    write_text(out / f"{NAME}.md", text, what="--out")
    finite = [{k: (None if isinstance(v, float) and not math.isfinite(v) else v)
               for k, v in r.items()} for r in summ]
    return Result(NAME, TITLE, uniform(rows + broken), {"summary": finite, "markdown": text,
                                               "draws": count, "master_seed": seed})


def run_rows(indices, seed: int, cfg: dict, progress: Path | None = None) -> tuple:
    """(rows, broken): each draw's row, and the draws this harness could not run (its own
    error, not the commands': those are rows), each a row with its traceback's last line."""
    from . import run
    rows, broken = [], []
    if progress is not None:
        progress.unlink(missing_ok=True)
    with tempfile.TemporaryDirectory(prefix="nlos-cl-scenarios-") as work:
        for i in tqdm(list(indices), desc=NAME, disable=len(indices) < 2):
            folder = Path(work) / f"draw-{i}"
            try:
                row = run.run(dr.draw(i, seed, cfg), cfg, folder)
                rows.append(row)
            except Exception:  # noqa: BLE001 - one broken draw must not lose the others
                row = {"index": i, "family": dr.family_of(i, cfg), "exit": "harness",
                       "why": traceback.format_exc().strip().splitlines()[-1][:300]}
                broken.append(row)
            if progress is not None:
                with open(progress, "a", encoding="utf-8") as f:
                    f.write(json.dumps(row, default=str) + "\n")
            _remove(folder)
    if progress is not None:
        progress.unlink(missing_ok=True)
    return rows, broken


def _remove(folder: Path) -> None:
    import shutil
    shutil.rmtree(folder, ignore_errors=True)


def page(rows, broken, summ, cfg, options: str, seconds: float, seed: int) -> str:
    """The page, from the rows only."""
    fail = cfg["failure_m"]
    header = (f"# {TITLE}\n\nGenerated by `nlos-cl reproduce scenarios{options}` on "
              f"{nl.resolve_backend().name}, {os.cpu_count()} CPU cores, in {seconds / 60:.1f} "
              f"min: {len(rows) + len(broken)} draws, master seed {seed}; the ranges: "
              "nlos_cl/apps/reproduce/scenarios/scenarios.yaml. Every draw's row is in "
              "scenarios.csv beside this page. Do not edit by hand.")
    drawn = len(rows) + len(broken)
    if drawn < cfg["draws"]:
        header += (f" This run drew {drawn} scenes, not the {cfg['draws']} of a full run: "
                   "the rates below are over these.")
    how = ("Each draw is a scene file a user could have written (docs/scene-files.md: wall "
           "spots in a triangle, circle, SPAD patch or at random, never in a line; facets "
           f"{cfg['facet_size_m'] * 100:g} cm; white noise at {cfg['snr_db'][0]:g}-"
           f"{cfg['snr_db'][1]:g} dB unless photons are counted), run as a user types it: "
           "`nlos-cl simulate scene.yaml --out f.h5`, then `nlos-cl locate f.h5 --json` "
           "with no option (a sequence: `nlos-cl track seq.h5 --json`). Draw i is of family "
           f"i mod {len(cfg['families'])}, in the order below, and a pure function of (i, "
           "master seed): `nlos_cl.apps.reproduce.scenarios.rerun(i, folder)` re-runs it, "
           "leaving its files in folder.")
    rule = ("Found targets are matched to the truths (bounding-box centres; an occluder is a "
            "truth, furniture is not) by linear assignment on distance. A truth is *lit* "
            f"where at least {cfg['lit_share']:g} of its light (facet-spot pairs facing both "
            "spots, by area) passes every other object, else *shadowed*. A draw **fails** "
            "where the command refused or crashed, where any lit truth is missed or found "
            f"more than {fail:g} m away, where the number found is below the lit truths or "
            "above all truths (right K), or where a shadowed truth is missed and lies in no "
            "shadow the answer declared (its JSON's `shadowed`: behind a found target as the "
            "laser spot sees it; a geometry check, not words). The error is the worst over lit truths ('missed'"
            ": none assigned). A sequence is scored from frame "
            f"{cfg['clutter']['first_frame']} on: each mover's error is its median over the "
            "frames it is lit, against the confirmed tracks of each frame; the number found is "
            "the most frequent number of confirmed tracks. 'Without a warning': a failure "
            "whose answer carried no warning and no refusal message.")
    families = "\n".join(f"- **{f}**: {FAMILIES[f]}" for f in cfg["families"])
    sections = [header, how, "Families (draws.py, sequences.py; ranges in scenarios.yaml):",
                families, rule, "## Overall and per family", report.summary_table(summ),
                "## By sub-range", report.kind_table(report.by_kind(rows, cfg["families"])),
                "## Every failure, worst first", report.failures_table(rows)]
    if broken:
        sections += ["## Draws the harness could not run",
                     report.table(["draw", "family", "error"],
                                  [[b["index"], b["family"], b["why"]] for b in broken])]
    return "\n\n".join(sections) + "\n"


def write_doc(result: Result, path: Path) -> None:
    """The run's page at `path` (--doc), atomically and never through a link; whether it may
    be replaced was checked before the run (reproduce_cmd._check_outputs)."""
    from ....io.safe_write import write_text
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, result.summary["markdown"], what="--doc", keep_unless=lambda _: True)


def rerun(index: int, folder, master_seed: int | None = None) -> dict:
    """Draw `index` alone, as the full run ran it: its row (its files stay in folder)."""
    from . import run
    cfg = dr.config()
    return run.run(dr.draw(index, master_seed, cfg), cfg, Path(folder))
