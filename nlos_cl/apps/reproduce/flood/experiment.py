"""`nlos-cl reproduce flood`: the flood study: how far nlos_cl's confocal
reading of a consumer multizone sensor's captures moves a location, measured on simulations of
that sensor (study says what is simulated, flood.yaml every number; report writes the page).

Writes OUT/flood.csv (a row per draw, by `reproduce.run`) and OUT/flood.md; with --doc, that
page there (docs/results/flood/flood.md) and flood.csv beside it. Not part of `reproduce all`;
--quick runs flood.yaml's quick_draws targets, `draws=N` (the CLI's --draws) N. About 3 s a
draw on 2 CPU cores (PoCL)."""
from __future__ import annotations

import time
from pathlib import Path

from tqdm import tqdm

from ....core.errors import require
from ..common import Result, Settings, write_csv
from . import report, study

NAME = "flood"
TITLE = "A multizone sensor's flood, read as confocal: the error measured"


def flood(s: Settings, out: Path, draws: int | None = None) -> Result:
    """`draws` targets (default flood.yaml's; --quick: quick_draws), each simulated as flood
    and as confocal data and located three ways (study.run_draw); the page OUT/flood.md."""
    from ....io.safe_write import write_text
    cfg = study.config()
    count = draws or (cfg["quick_draws"] if s.quick else cfg["draws"])
    require(isinstance(count, int) and count >= 1, "--draws", f"must be a positive whole "
            f"number, got {count!r}", "pass e.g. --draws 40")
    sensor = study.MultizoneSensor.from_config(cfg["sensor"])
    start = time.perf_counter()
    rows = [study.run_draw(study.draw(i, cfg), cfg, sensor)
            for i in tqdm(range(count), desc=NAME, disable=count < 2)]
    stats, seconds = study.summary(rows), time.perf_counter() - start
    options = (" --quick" if s.quick else "") + (f" --draws {draws}" if draws else "")
    text = report.page(stats, cfg, seconds, count, options)
    out.mkdir(parents=True, exist_ok=True)
    write_text(out / f"{NAME}.md", text, what="--out")
    return Result(NAME, TITLE, rows, {"stats": stats, "markdown": text})


def write_doc(result: Result, path: Path) -> None:
    """The run's page at `path` (--doc: docs/results/flood/flood.md), atomically and never
    through a link, and its rows beside it as flood.csv. Whether the page may be replaced was
    checked before the run (reproduce_cmd._check_outputs), as for the draws' page."""
    from ....io.safe_write import write_text
    path.parent.mkdir(parents=True, exist_ok=True)
    write_csv(path.with_name(f"{NAME}.csv"), result.rows)
    write_text(path, result.summary["markdown"], what="--doc", keep_unless=lambda _: True)
