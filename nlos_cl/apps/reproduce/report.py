"""The report (docs/results/paper/paper-results.md): every experiment's numbers from this run, the
paper's beside them, the settings, and the remarks (text.yaml) on where and why they differ; the
JSON summary that `--json` prints; and the aligned table `nlos-cl reproduce` prints."""
from __future__ import annotations

import json
import math
from pathlib import Path

import nlos_cl as nl

from .common import METHODS, TEXT, Result, Settings


def summary_json(results) -> str:
    if len(results) == 1:
        return json.dumps(results[0].summary)
    return json.dumps({r.name: r.summary for r in results})


def _pm(st, prefix=""):
    return f"{st[prefix + 'mean_m']:.4f} ± {st[prefix + 'std_m']:.4f} (max {st[prefix + 'max_m']:.4f})"


def _xy(x, y):
    return f"({x:.3f}, {y:.3f})"


def _table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _fig5(r: Result) -> str:
    return _table(["detector", "paper FWHM (ns)", "ours: clean signal", "ours: filtered h=0.8 ns",
                   "ours: Gauss fit"],
                  [(x["detector"], x["paper_fwhm_ns"], x["fwhm_clean_ns"], x["fwhm_filtered_ns"],
                    x["fwhm_fit_ns"]) for x in r.rows])


def _fig6(r: Result) -> str:
    return _table(["signal", "paper (x, y)", "ours (x, y), mean over seeds",
                   "ours: error mean ± std (max), m"],
                  [(x["method"], f"({x['paper_x']}, {x['paper_y']})", _xy(x["x"], x["y"]), _pm(x))
                   for x in r.rows])


def _methods_sweep(key, label):
    def section(r: Result) -> str:
        return _table([label, "filter: error mean ± std (max), m",
                       "fit: error mean ± std (max), m"],
                      [(x[key], _pm(x, "filter_"), _pm(x, "fit_")) for x in r.rows])
    return section


def _fig7b(r: Result) -> str:
    return _table(["h (ns)", "filter: error mean ± std (max), m", "located (x, y)"],
                  [(x["h_ns"], _pm(x, "filter_"), _xy(x["filter_x"], x["filter_y"]))
                   for x in r.rows])


def _paper_positions(key, label, extra=()):
    """Our filter's position beside the paper's; `extra`: (column title, row key) pairs."""
    def section(r: Result) -> str:
        return _table([label, "paper (x, y)", "ours: filter (x, y)", "ours: filter error (m)",
                       "ours vs paper (m)"] + [head for head, _ in extra],
                      [(x[key], f"({x['paper_x']}, {x['paper_y']})", _xy(x["x"], x["y"]),
                        x["error_mean_m"], x["distance_to_paper_m"])
                       + tuple(x[k] for _, k in extra) for x in r.rows])
    return section


def _mean_std_max(d):
    return f"{d['mean_m']:.4f} ± {d['std_m']:.4f}" + (f" (max {d['max_m']:.4f})"
                                                      if "max_m" in d else "")


def _fig10(r: Result) -> str:
    paper = r.summary["paper"]
    return _table(["signal", "paper: error mean ± std (max), m", "ours: error mean ± std (max), m"],
                  [(m, _mean_std_max(paper[m]) if m in paper else "-",
                    _mean_std_max(r.summary[m])) for m in METHODS])


SECTIONS = {
    "fig5": _fig5, "fig6": _fig6,
    "fig7a": _methods_sweep("delta_m", "detector spacing (m)"), "fig7b": _fig7b,
    "table1": _paper_positions("fwhm_ps", "laser FWHM (ps)"),
    "fig8": _paper_positions("target_m", "rectangle (m)",
                             [("ours: fit error (m)", "fit_error_mean_m")]),
    "fig9": _methods_sweep("side_m", "square side (m)"), "fig10": _fig10,
}


def _section(r: Result) -> str:
    """The markdown table of one experiment: the paper's numbers beside ours."""
    return SECTIONS[r.name](r) if r.name in SECTIONS else ""


def write_report(results, s: Settings, path: Path, out: Path, wall_s: float,
                 force: bool = False) -> None:
    """docs/results/paper/paper-results.md: every experiment's numbers from this run, the paper's
    beside them, the settings, and the remarks (text.yaml) on where and why they differ. Written
    atomically, never over a page nlos_cl did not generate unless `force` (safe_write)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        figure_dir = out.resolve().relative_to(path.parent.resolve())
    except ValueError:
        figure_dir = out.resolve()
    device = nl.resolve_backend().name
    parts = ["# The paper's numbers and ours", "",
             TEXT["header"].format(out=out, path=path, device=device, wall_s=wall_s), "",
             TEXT["intro"].format(settings=s.describe()), "", TEXT["general"], ""]
    for r in results:
        remark = TEXT["experiments"].get(r.name, {}).get("remark", "")
        parts += [f"## {r.title}", "", _section(r), "", remark, ""]
        parts += [f"![{r.name}]({figure_dir / png})" for png in r.figures]
        parts.append("")
    from ...io.safe_write import write_text
    write_text(path, "\n".join(parts), what="--doc", force=force)


# ----------------------------------------------------------------------------- the terminal

def _cell(value) -> str:
    """A table cell as a reader wants it: '-' where nothing was measured (NaN, None), floats
    to 4 significant digits, markdown emphasis dropped."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if isinstance(value, float):
        return f"{value:.4g}"
    text = str(value).replace("**", "")
    return "-" if text.strip().lower() == "nan" else text


def _markdown_tables(text: str) -> list[list[list[str]]]:
    """Every markdown table of `text`, as rows of cells (the separator line left out)."""
    tables, rows = [], []
    for line in text.splitlines() + [""]:
        if line.startswith("|"):
            if not set(line) <= set("|-: "):
                rows.append([_cell(c.strip()) for c in line.strip()[1:-1].split("|")])
        elif rows:
            tables.append(rows)
            rows = []
    return tables


def _dict_rows(dicts, limit: int = 40) -> list[list[str]]:
    """Dicts (a result's rows) as a header row and one row each (the first `limit`)."""
    columns = list(dict.fromkeys(k for d in dicts for k in d
                                 if not isinstance(d[k], (dict, list))))
    return [columns] + [
        [_cell(d.get(c, "")) for c in columns] for d in dicts[:limit]]


def aligned(rows: list[list[str]], indent: str = "  ") -> str:
    """Rows of cells (the first the header) as plain text in aligned columns."""
    width = max(map(len, rows))
    rows = [r + [""] * (width - len(r)) for r in rows]
    widths = [max(len(r[i]) for r in rows) for i in range(width)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(indent + line for line in lines)


def headline_tables(r: Result) -> list[list[list[str]]]:
    """What the terminal shows of one experiment: the paper's numbers beside ours (the paper's
    experiments), the page's first table per section (beyond, draws, flood, tracking), else
    the result's rows. The targets' checks stay in --json ("goals"), out of what is printed."""
    if r.name in SECTIONS:
        return _markdown_tables(_section(r))
    pages = r.summary.get("markdown")
    pages = pages.values() if isinstance(pages, dict) else [pages] if pages else []
    tables = [t[0] for t in map(_markdown_tables, pages) if t]
    return tables or ([_dict_rows(r.rows)] if r.rows else [])


def summary_text(results, out: Path, wall_s: float) -> str:
    """`nlos-cl reproduce`'s summary: per experiment its title, time, files and table."""
    parts = []
    for r in results:
        files = ", ".join([f"{r.name}.csv", *r.figures])
        parts.append(f"{r.name}: {r.title} ({r.seconds:.1f} s); files in {out}: {files}")
        parts += [aligned(t) for t in headline_tables(r)]
        parts.append("")
    return "\n".join(parts + [f"wall time {wall_s:.1f} s"])
