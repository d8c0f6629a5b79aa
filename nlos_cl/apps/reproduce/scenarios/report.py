"""The scenarios' tables, from the rows alone: per family (and overall) the failure rate, the
right-K rate, median / p90 / worst error and the failures that came without a warning; the
same per sub-range (a family's kind); every failure, worst first."""
from __future__ import annotations

import math

import numpy as np

COLUMNS = ("family", "draws", "failures", "failure_rate", "right_k_rate", "median_m", "p90_m",
           "worst_m", "failures_unwarned", "refused_or_crashed")


def _rank(values, q: float) -> float:
    """The nearest-rank quantile (an infinite error, a missed target, stays infinite)."""
    v = sorted(values)
    return v[max(0, math.ceil(q * len(v)) - 1)] if v else math.nan


def _stats(rows, name: str) -> dict:
    errors = [float(r["error_m"]) for r in rows]
    failed = [r for r in rows if r["failed"] in (True, "True")]
    return {"family": name, "draws": len(rows), "failures": len(failed),
            "failure_rate": round(len(failed) / len(rows), 4) if rows else math.nan,
            "right_k_rate": round(sum(r["right_k"] in (True, "True") for r in rows) / len(rows), 4)
            if rows else math.nan,
            "median_m": round(float(np.median(errors)), 4) if errors else math.nan,
            "p90_m": round(_rank(errors, 0.9), 4), "worst_m": round(_rank(errors, 1.0), 4),
            "failures_unwarned": sum(r["warned"] not in (True, "True") for r in failed),
            "refused_or_crashed": sum(r["exit"] != "0" for r in rows)}


def summary(rows, families) -> list[dict]:
    """One row per family that ran (in scenarios.yaml's order), then 'all'."""
    out = [_stats([r for r in rows if r["family"] == f], f) for f in families
           if any(r["family"] == f for r in rows)]
    return out + [_stats(rows, "all")]


def by_kind(rows, families) -> list[dict]:
    out = []
    for f in families:
        kinds = dict.fromkeys(r["kind"] for r in rows if r["family"] == f)
        for k in sorted(kinds, key=str):
            s = _stats([r for r in rows if r["family"] == f and r["kind"] == k], f)
            out.append({"family": f, "kind": k, **{c: s[c] for c in COLUMNS[1:]}})
    return out


def _num(v, unit: str = "") -> str:
    if isinstance(v, float) and math.isinf(v):
        return "missed"
    if isinstance(v, float) and math.isnan(v):
        return "-"
    return f"{v:.3f}{unit}" if isinstance(v, float) else str(v)


def _pct(v) -> str:
    return "-" if isinstance(v, float) and math.isnan(v) else f"{100 * v:.1f} %"


def table(header, lines) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return "\n".join(out + ["| " + " | ".join(str(c) for c in line) + " |" for line in lines])


def summary_table(summ) -> str:
    return table(["family", "draws", "failures", "failure rate", "right K", "median error",
                  "p90 error", "worst error", "failures without a warning",
                  "refused or crashed"],
                 [[s["family"] if s["family"] != "all" else "**all**", s["draws"],
                   s["failures"], _pct(s["failure_rate"]), _pct(s["right_k_rate"]),
                   _num(s["median_m"], " m"), _num(s["p90_m"], " m"), _num(s["worst_m"], " m"),
                   s["failures_unwarned"], s["refused_or_crashed"]] for s in summ])


def kind_table(kinds) -> str:
    return table(["family", "sub-range", "draws", "failures", "failure rate", "right K",
                  "median error", "worst error", "without a warning"],
                 [[k["family"], k["kind"], k["draws"], k["failures"], _pct(k["failure_rate"]),
                   _pct(k["right_k_rate"]), _num(k["median_m"], " m"), _num(k["worst_m"], " m"),
                   k["failures_unwarned"]] for k in kinds])


def _cell(text: str, n: int) -> str:
    text = str(text).replace("|", "/").replace("\n", " ")
    return text if len(text) <= n else text[:n - 3] + "..."


def failures_table(rows) -> str:
    failed = [r for r in rows if r["failed"] in (True, "True")]
    if not failed:
        return "No draw failed."
    failed.sort(key=lambda r: (-float(r["error_m"]), r["index"]))
    return table(["draw", "family", "sub-range", "targets", "error", "found", "why",
                  "warned", "what the answer said"],
                 [[r["index"], r["family"], r["kind"], r["shapes"],
                   _num(float(r["error_m"]), " m"), f"{r['found']} of {r['truths']}",
                   r["why"], "yes" if r["warned"] in (True, "True") else "**no**",
                   _cell(r["said"], 160)] for r in failed])
