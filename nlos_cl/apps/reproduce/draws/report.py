"""The tables of `reproduce draws`, from its CSV rows only: per family (mismatch: per
sub-family) and estimator the error distribution, failures and unwarned failures, K picked
right (multi); the targets checked; where the layouts and shapes fail; the worst draws,
with what re-runs each alone. A missed target (fewer found than there are) counts as an
infinite error: it fails, and it is above every percentile it reaches."""
from __future__ import annotations

import math

import numpy as np

GROUP = ("family", "sub", "estimator")


def _errors(rows) -> np.ndarray:
    e = np.array([float(r["error_m"]) for r in rows], float)
    return np.where(np.isnan(e), np.inf, e)


def _bool(v) -> bool:
    return v is True or str(v) == "True"


def stats(rows, failure_m: float) -> dict:
    """n, median, p90, worst, failure rate, unwarned failures, K right, median time."""
    e = _errors(rows)
    fail = e > failure_m
    k_right = [int(r["k_found"]) == int(r["k_true"]) for r in rows]
    seconds = [float(r["seconds"]) for r in rows]
    return {"n": len(rows), "median_m": float(np.median(e)),
            "p90_m": float(np.percentile(e, 90)) if np.isfinite(e).all()
            else float(np.sort(e)[min(len(e) - 1, math.ceil(0.9 * len(e)) - 1)]),
            "worst_m": float(e.max()), "failure_rate": float(fail.mean()),
            "unwarned_failures": int(sum(f and not _bool(r["warned"]) for f, r in zip(fail, rows))),
            "k_right": float(np.mean(k_right)), "median_s": float(np.median(seconds)),
            "spread_s": float(np.percentile(seconds, 75) - np.percentile(seconds, 25))}


def groups(rows, keys=GROUP) -> dict:
    out: dict = {}
    for r in rows:
        out.setdefault(tuple(r[k] for k in keys), []).append(r)
    return out


# The one-target targets hold for "any layout of >= 3 non-degenerate spots": spots on one
# line with the laser spot leave the height unobservable (draws.yaml's min_spread_m), so the
# one and closed families also get a row without their line layouts.
OFF_LINE = "off a line"
# The closed target holds "from layouts that see them from two sides or say they cannot": the
# off-line draws whose default answer did not say the spots cannot see the target's depth (the
# paper's argmax never says so: its row would repeat the off-line one, so it has none).
TWO_SIDES = "seen from two sides"


def summary(rows, failure_m: float) -> list[dict]:
    """One row per family (mismatch: per sub-family; the others: all shapes together) and
    estimator; for one and closed also their draws whose spots are not on a line (OFF_LINE)."""
    keyed = [{**r, "sub": r["sub"] if r["family"] == "mismatch" else "all"} for r in rows]
    keyed += [{**r, "sub": OFF_LINE} for r in rows if r["family"] in ("one", "closed")
              and not str(r["layout"]).startswith("line")]
    keyed += [{**r, "sub": TWO_SIDES} for r in rows if r["family"] == "closed"
              and r["estimator"] != "paper" and not str(r["layout"]).startswith("line")
              and not _bool(r.get("depth_unseen"))]
    return [{"family": f, "sub": sub, "estimator": est, **stats(g, failure_m)}
            for (f, sub, est), g in groups(keyed).items()]


def _m(v: float) -> str:
    return "inf" if not math.isfinite(v) else f"{v:.4f}"


def summary_table(summ) -> str:
    head = ("| family | sub-family | estimator | n | median (m) | p90 (m) | worst (m) | failures "
            "(> 0.15 m) | beyond 0.15 m without a warning | K right | time median (IQR) s |\n"
            "|---|---|---|---|---|---|---|---|---|---|---|")
    lines = [head]
    for r in summ:
        k = f"{r['k_right']:.0%}" if r["family"] == "multi" else "-"
        lines.append(f"| {r['family']} | {r['sub']} | {r['estimator']} | {r['n']} | "
                     f"{_m(r['median_m'])} | {_m(r['p90_m'])} | {_m(r['worst_m'])} | "
                     f"{r['failure_rate']:.1%} | {r['unwarned_failures']} | {k} | "
                     f"{r['median_s']:.2f} ({r['spread_s']:.2f}) |")
    return "\n".join(lines)


def _find(summ, family, estimator, sub="all"):
    return next((r for r in summ if (r["family"], r["sub"], r["estimator"]) ==
                 (family, sub, estimator)), None)


def goals(summ) -> list[dict]:
    """The targets, each with what was measured; families not run are left out."""
    out = []

    def goal(what, row, measured, target, met):
        if row is not None:
            out.append({"goal": what, "n": row["n"], "measured": measured, "target": target,
                        "met": met})
    one = _find(summ, "one", "default")
    if one:
        goal("one target: default median", one, _m(one["median_m"]), "<= 0.01 m",
             one["median_m"] <= 0.01)
        goal("one target: default p90", one, _m(one["p90_m"]), "<= 0.03 m", one["p90_m"] <= 0.03)
        goal("one target: default beyond 0.15 m without a warning", one,
             str(one["unwarned_failures"]), "0", one["unwarned_failures"] == 0)
    off = _find(summ, "one", "default", OFF_LINE)
    if off:
        goal(f"one target, spots {OFF_LINE}: default median", off, _m(off["median_m"]),
             "<= 0.01 m", off["median_m"] <= 0.01)
        goal(f"one target, spots {OFF_LINE}: default p90", off, _m(off["p90_m"]), "<= 0.03 m",
             off["p90_m"] <= 0.03)
        goal(f"one target, spots {OFF_LINE}: beyond 0.15 m without a warning", off,
             str(off["unwarned_failures"]), "0", off["unwarned_failures"] == 0)
    for sub in sorted({r["sub"] for r in summ if r["family"] == "mismatch"}):
        d, p = _find(summ, "mismatch", "default", sub), _find(summ, "mismatch", "paper", sub)
        if d and p:
            gap = d["p90_m"] - p["p90_m"]
            goal(f"mismatch {sub}: default p90 - paper p90", d, _m(gap), "<= 0.02 m",
                 gap <= 0.02)
    k, auto = _find(summ, "multi", "default K"), _find(summ, "multi", "default auto")
    if k:
        goal("multi: default (K given) p90", k, _m(k["p90_m"]), "<= 0.10 m", k["p90_m"] <= 0.10)
    if auto:
        goal("multi: auto K right", auto, f"{auto['k_right']:.0%}", ">= 90 %",
             auto["k_right"] >= 0.9)
    closed = _find(summ, "closed", "default")
    if closed:
        goal("closed: default centre p90", closed, _m(closed["p90_m"]), "<= 0.10 m",
             closed["p90_m"] <= 0.10)
    off = _find(summ, "closed", "default", OFF_LINE)
    if off:
        goal(f"closed, spots {OFF_LINE}: default centre p90", off, _m(off["p90_m"]),
             "<= 0.10 m", off["p90_m"] <= 0.10)
    two = _find(summ, "closed", "default", TWO_SIDES)
    if two and off:
        goal(f"closed, {TWO_SIDES} (the {off['n'] - two['n']} answers saying the spots cannot "
             "see the depth left out): default centre p90", two, _m(two["p90_m"]),
             "<= 0.10 m", two["p90_m"] <= 0.10)
    return out


def breakdown_table(rows, failure_m: float, by: str) -> str:
    """Per family, estimator and `by` (layout or shapes): n, median, p90, failures."""
    lines = [f"| family | estimator | {by} | n | median (m) | p90 (m) | failures |",
             "|---|---|---|---|---|---|---|"]
    for (f, est, key), g in sorted(groups(rows, ("family", "estimator", by)).items()):
        st = stats(g, failure_m)
        lines.append(f"| {f} | {est} | {key} | {st['n']} | {_m(st['median_m'])} | "
                     f"{_m(st['p90_m'])} | {st['failure_rate']:.0%} |")
    return "\n".join(lines)


def worst_table(rows, count: int = 5) -> str:
    """The `count` worst draws per family and estimator, each with its re-run call."""
    lines = ["| family | estimator | error (m) | index | master seed | layout | shapes | sub | "
             "warned | warnings |", "|---|---|---|---|---|---|---|---|---|---|"]
    for (f, est), g in groups(rows, ("family", "estimator")).items():
        order = np.argsort(-_errors(g), kind="stable")[:count]
        for i in order:
            r = g[int(i)]
            lines.append(f"| {f} | {est} | {_m(_errors([r])[0])} | {r['index']} | "
                         f"{r['master_seed']} | {r['layout']} ({r['spots']}) | {r['shapes']} | "
                         f"{r['sub']} | {r['warned']} | {str(r['warnings'])[:80]} |")
    return "\n".join(lines)
