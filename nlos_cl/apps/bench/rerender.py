"""Re-render a bench page from the performance.json beside it, without benching again (a run
on a machine that is gone: docs/results/nvidia/ holds an H200's):

    python -m nlos_cl.apps.bench.rerender docs/results/nvidia/performance.json

rewrites performance.md beside the JSON with today's table format and text around the run's
own rows (every number is that run's; the figure is left as it was). Older runs wrote checks
against targets into the rows' notes ('goal (issue N) ... met'): those parts of a note are
left out, as a bench run leaves them out now."""
from __future__ import annotations

import json
import re
import sys
from dataclasses import fields
from importlib import resources
from pathlib import Path

from ...core.errors import require
from .cases import Row
from .model_paths import section
from .report import HEADER, pf_peer_section, table

CHECK = re.compile(r"^(goal|target)\b.*(\bmet|: yes|: no)$|^goal \(issue", re.IGNORECASE)


def measured_note(note: str) -> str:
    """A row's note without its checks against targets."""
    return "; ".join(p for p in note.split("; ") if not CHECK.search(p.strip()))


def rows_of(data: dict) -> list[Row]:
    names = {f.name for f in fields(Row)}
    return [Row(**({k: v for k, v in r.items() if k in names}
                   | {"note": measured_note(r.get("note", ""))})) for r in data["rows"]]


def rerender(json_path: Path) -> Path:
    """Write performance.md beside `json_path` from its rows; returns the page's path."""
    try:
        data = json.loads(json_path.read_text("utf-8"))
    except (OSError, ValueError) as exc:
        data = {"error": str(exc)}
    keys = {"device", "smoke", "rows"}
    require(set(data) in (keys, keys | {"model_paths"}), str(json_path), "is not the "
            "performance.json of a bench run", "pass the JSON `nlos-cl bench --out` wrote")
    page = json_path.with_name("performance.md")
    require(not page.exists() or page.read_text("utf-8").startswith("# Performance\n"),
            str(page), "is not a bench page", "move it away, or re-render a copy elsewhere")
    analysis = resources.files(__package__).joinpath("analysis.md").read_text()
    text = ("# Performance\n\n" + HEADER + f" This page was re-rendered from {json_path} (the "
            "rows of that run, on the device below) by `python -m nlos_cl.apps.bench.rerender "
            f"{json_path}`: every number in the table is that run's; the text around it is "
            f"today's.\n\nDevice: {data['device']}\n\n" + table(rows_of(data)) + "\n"
            + section(data.get("model_paths"))
            + "\n![time against problem size](performance.png)\n\n"
            + pf_peer_section(json_path.with_name("performance-pf-peer.json")) + "\n" + analysis)
    from ...io.safe_write import write_text
    write_text(page, text, what="page", force=True)
    return page


if __name__ == "__main__":  # pragma: no cover - a maintainer's command
    for arg in sys.argv[1:]:
        print(rerender(Path(arg)))
