"""The report of `reproduce beyond` (docs/results/beyond/beyond-the-paper.md): per-case statistics
of both estimators, the model's 95 % region coverage, the targets checked against this run, and
remarks computed from the numbers. Prose templates and targets are in text.yaml."""
from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

import numpy as np

import nlos_cl as nl

from ..common import Settings, load_data

TEXT: dict = load_data("text.yaml", __package__)


def _r(v, digits=4):
    return round(float(v), digits) if np.isfinite(v) else math.nan


def _notes(entry) -> str:
    """The entry's note, then every distinct frame note with how many frames carried it."""
    firsts = [r for r in entry["rows"] if r["target"] == 0]
    counts = Counter(n for r in firsts for n in filter(None, r["notes"].split("; ")))
    parts = [entry["note"]] if entry["note"] else []
    parts += [f"{n} ({c}/{len(firsts)} frames)" for n, c in counts.items()]
    return "; ".join(parts)


def summarise(entry) -> list[dict]:
    """One summary row per measure of an entry: mean / max of both estimators' errors."""
    rows = entry["rows"]
    firsts = [r for r in rows if r["target"] == 0]
    t = np.array([r["model_s"] for r in firsts], float)
    tested = [r["inside95"] for r in rows if r["inside95"] != ""]
    out = []
    for m in entry["measures"]:
        p = np.array([r[f"paper_{m}_m"] for r in rows], float)
        mo = np.array([r[f"model_{m}_m"] for r in rows], float)
        ok = np.isfinite(mo)
        out.append({
            "section": entry["section"], "case": entry["case"], "measure": m,
            "value": entry.get("value", ""), "frames": len(firsts), "errors": len(rows),
            "paper_mean_m": _r(np.mean(p)), "paper_max_m": _r(np.max(p)),
            "model_mean_m": _r(np.mean(mo[ok])) if ok.any() else math.nan,
            "model_max_m": _r(np.max(mo[ok])) if ok.any() else math.nan,
            "model_failed": int((~ok).sum()), "model_s_mean": _r(t.mean(), 3),
            "model_s_max": _r(t.max(), 3), "inside95": int(sum(tested)), "tested95": len(tested),
            "note": _notes(entry)})
    return out


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """The Wilson score interval of a binomial proportion k / n."""
    if n == 0:
        return math.nan, math.nan
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return centre - half, centre + half


def _coverage_row(group, rows) -> dict:
    tested = [r["inside95"] for r in rows if r["inside95"] != ""]
    k, n = int(sum(tested)), len(tested)
    lo, hi = wilson(k, n)
    return {"group": group, "tested": n, "inside": k, "fraction": _r(k / n, 3) if n else math.nan,
            "interval_low": _r(lo, 3), "interval_high": _r(hi, 3),
            "consistent_with_95": bool(n and lo <= 0.95 <= hi)}


def coverage_rows(entries) -> list[dict]:
    """How often the truth is inside the model's 95 % region: per coverage case, then pooled
    over groups of sections (every frame of this run that has a covariance)."""
    out = [_coverage_row(e["case"], e["rows"]) for e in entries if e["section"] == "coverage"]
    for group, sections in TEXT["coverage_groups"].items():
        rows = [r for e in entries if e["section"] in sections for r in e["rows"]]
        if rows:
            out.append(_coverage_row(group, rows))
    return out


def goal_rows(summary, entries) -> list[dict]:
    """The targets (text.yaml's goals), each checked on the worst matching case of this run."""
    out = []
    for g in TEXT["goals"]:
        rows = [r for r in summary if r["section"] == g["section"]
                and r["measure"] == g.get("measure", "err3d") and g.get("case", "") in r["case"]]
        rows = rows[-1:] if g.get("last") else rows
        values = [r[g["stat"]] for r in rows if np.isfinite(r[g["stat"]])]
        failed = sum(r["model_failed"] for r in rows)
        if g["section"] == "coverage_all":
            cov = [c for c in coverage_rows(entries) if c["group"] == g["group"]]
            values = [c["fraction"] for c in cov if c["tested"]]
        worst = (min(values) if g.get("min") is not None else max(values)) if values else None
        met = worst is not None and not failed and (g.get("max") is None or worst <= g["max"]) \
            and (g.get("min") is None or worst >= g["min"])
        out.append({"goal": g["goal"], "measured": "not measured" if worst is None else worst,
                    "met": "not measured" if worst is None else ("yes" if met else "no")
                    + (f" ({failed} fits failed)" if failed else "")})
    return out


def _table(header, rows) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _mm(a, b) -> str:
    return "failed" if not np.isfinite(a) else f"{a:.3f} / {b:.3f}"


def cases_table(summary) -> str:
    t = TEXT["table"]
    return _table(t["header"], [
        (TEXT["sections"][r["section"]]["short"], r["case"], t["measures"][r["measure"]],
         r["frames"], _mm(r["paper_mean_m"], r["paper_max_m"]),
         _mm(r["model_mean_m"], r["model_max_m"])
         + (f" ({r['model_failed']} failed)" if r["model_failed"] else ""),
         f"{r['model_s_mean']:.2f} / {r['model_s_max']:.2f}",
         f"{r['inside95']}/{r['tested95']}" if r["tested95"] else "-", r["note"] or "")
        for r in summary])


def _remarks(summary) -> list[str]:
    """Data-driven remarks per section: where the model wins, its worst case, failures."""
    out, tpl = [], TEXT["remarks"]
    for key, sec in TEXT["sections"].items():
        rows = [r for r in summary if r["section"] == key]
        if not rows:
            continue
        fin = [r for r in rows if np.isfinite(r["model_mean_m"])]
        wins = sum(r["model_mean_m"] < r["paper_mean_m"] for r in fin)
        text = tpl["wins"].format(title=sec["title"], wins=wins, n=len(rows))
        if fin:
            worst = max(fin, key=lambda r: r["model_max_m"])
            text += " " + tpl["worst"].format(case=worst["case"], max=worst["model_max_m"],
                                              measure=TEXT["table"]["measures"][worst["measure"]])
        failed = sum(r["model_failed"] for r in rows)
        if failed:
            text += " " + tpl["failed"].format(failed=failed)
        out.append(f"- {text} {sec.get('remark', '')}".rstrip())
    return out


def write_beyond_report(result, s: Settings, path: Path, out: Path, wall_s: float,
                        force: bool = False) -> None:
    """docs/results/beyond/beyond-the-paper.md, atomically; never over a page nlos_cl did not
    generate unless `force` (nlos_cl.io.safe_write)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        fig_dir = out.resolve().relative_to(path.parent.resolve())
    except ValueError:
        fig_dir = out.resolve()
    summ = result.summary
    quick = " --quick" if s.quick else ""
    parts = [f"# {result.title}", "",
             TEXT["header"].format(out=out, path=path, quick=quick, wall_s=wall_s,
                                   device=nl.resolve_backend().name), "",
             TEXT["settings"].format(seeds=s.seeds, snr_db=s.snr_db, facet_cm=s.facet_m * 100,
                                     step_cm=s.grid_step_m * 100, h_ns=s.h_s * 1e9,
                                     dt_ps=s.dt_s * 1e12), "", TEXT["intro"], "",
             "## " + TEXT["titles"]["cases"], "", TEXT["cases_intro"], "",
             cases_table(summ["summary"]), "", *[f"![{p}]({fig_dir / p})" for p in result.figures],
             "", "## " + TEXT["titles"]["coverage"], "", TEXT["coverage_intro"], "",
             _table(TEXT["coverage_header"],
                    [(c["group"], c["tested"], c["inside"], c["fraction"],
                      f"[{c['interval_low']}, {c['interval_high']}]",
                      "yes" if c["consistent_with_95"] else "no") for c in summ["coverage"]]), "",
             "## " + TEXT["titles"]["remarks"], "", *_remarks(summ["summary"]), "",
             "## " + TEXT["titles"]["sections"], "",
             *[f"- **{v['title']}**: {v['about']}" for v in TEXT["sections"].values()], "",
             "## " + TEXT["titles"]["model"], "", TEXT["model"], ""]
    from ....io.safe_write import write_text
    write_text(path, "\n".join(parts), what="--doc", force=force)
