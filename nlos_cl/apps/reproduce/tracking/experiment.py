"""`nlos-cl reproduce tracking`: how well the tracker follows hidden objects (docs/tracking.md,
"Measured"). Sections: lines (straight and curved paths, two layouts, the paper's and the model
estimator; the causal filter, a fixed lag and the offline RTS smoother, against the causal
bound), synthetic (the constant-velocity filter alone on the bound's paths with white errors:
what its process noise allows), box (static clutter, with and without background removal),
crossing (two targets; are identities kept?), speed (frames/s) and memory (peak RSS tracking a
long sequence file). The cases live in tracking.yaml (none in code; cases checks them).

Writes OUT/tracking.csv (per section: seconds and rows), OUT/tracking-<section>.csv (each
table's rows) and OUT/tracking.md (every section's markdown between the markers that
docs/tracking.md holds; report.splice puts them there). Not part of `reproduce all`."""
from __future__ import annotations

import os
import time
import warnings
from pathlib import Path

import nlos_cl as nl
from nlos_cl.core.errors import require

from ..common import Result, Settings, write_csv
from . import report

NAME = "tracking"
TITLE = "Tracking hidden objects: accuracy against the bound, clutter, a crossing, speed, memory"


def tracking(s: Settings, out: Path, only=None, cold: bool = False) -> Result:
    """Run tracking.yaml's sections (or those named in `only`); `cold`: trackers
    with warm_start=False (every model fit from its frame alone: the numbers before warm
    starts, for comparison, not for docs/tracking.md). s.quick picks the quick setting; the
    seeds, facets and grid are tracking.yaml's (s.seeds is not used)."""
    # here, not at the top: nlos_cl.tracking and the model estimator cost ~55 ms to import,
    # which listing reproduce's experiments (`nlos-cl reproduce fig5`) need not pay
    from . import sections
    from .cases import SECTIONS, Common, config
    cfg = config(s.quick)
    c = Common.of(cfg, cold)
    out.mkdir(parents=True, exist_ok=True)
    if only is not None:
        bad = [n for n in only if n not in SECTIONS]
        require(not bad, "--only", f"unknown section {bad[:1]}", f"use some of {list(SECTIONS)}")
    names = cfg["sections"] if only is None else [n for n in SECTIONS if n in only]
    texts, index, summary = {}, [], {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # collinear spots: the model estimator's height warning
        for name in names:
            start = time.perf_counter()
            rows, texts[name] = getattr(sections, name)(cfg, c)
            seconds = time.perf_counter() - start
            write_csv(out / f"{NAME}-{name}.csv", rows)
            index.append({"section": name, "seconds": round(seconds, 1), "rows": len(rows),
                          "csv": f"{NAME}-{name}.csv"})
            summary[name] = rows
    device = nl.resolve_backend().name
    options = (" --quick" if s.quick else "") + (" --cold" if cold else "") + (
        " --only " + " ".join(names) if only is not None else "")
    header = (f"# {TITLE}\n\nWritten by `nlos-cl reproduce tracking{options}` on {device}, "
              f"{os.cpu_count()} CPU cores; the cases: "
              "nlos_cl/apps/reproduce/tracking/tracking.yaml. Do not edit by hand.")
    from ....io.safe_write import write_text
    write_text(out / f"{NAME}.md", report.page(texts, header), what="--out")
    return Result(NAME, TITLE, index, {"warm_start": c.tracker["warm_start"], "quick": s.quick,
                                       "sections": summary, "markdown": texts})


def write_doc(result: Result, path: Path) -> None:
    """Put a run's sections into docs/tracking.md (`path`) between their markers. A cold run
    (warm_start=False) is refused: the page holds the warm-started numbers."""
    require(result.summary["warm_start"], "--doc", "a cold run (warm_start=False) is for "
            "comparison only", "run without --cold to update the page")
    report.splice(path, result.summary["markdown"])
