"""One draw of `reproduce draws`, run: simulate, add noise, locate with the paper's argmax and
with the library's default estimator (nl.locate_capture as `nlos-cl locate` calls it: the
derived search region, the automatic log mode, warnings collected), and per estimator one CSV
row: the errors (matched to the truths by linear assignment), K found, warnings and time."""
from __future__ import annotations

import json
import math
import time

import numpy as np

import nlos_cl as nl

from ....simulation.draws import scenes
from ..common import Settings

# Said for every collinear layout whatever the answer (z, or x for a vertical line, is held on
# the spots' plane, where the draws put the truth): not a sign that this answer is off, so
# not counted as a warning.
INFORMATIONAL = ("height (up the wall) is unobservable",
                 "the position across a vertical line of wall spots is unobservable")
# Said where the spots cannot tell how deep one target is (model.depth): a warning about a
# closed object's centre, which says nothing about a plate's, whose centre is its surface's.
DEPTH_UNSEEN = ("the spots see only the front of target", "the depth of target")
CLOSED_SHAPES = ("box", "sphere", "cylinder")


def estimators(d: dict) -> list[tuple[str, dict]]:
    """(label, locate_capture options): the paper's argmax and the default; for several
    targets the default told K, and the default choosing K itself."""
    if d["family"] != "multi":
        return [("paper", {"estimator": "paper"}), ("default", {})]
    k = len(d["targets"])
    return [("paper", {"estimator": "paper"}), ("default K", {"targets": k}),
            ("default auto", {"targets": "auto"})]


def matched_errors(found, truths) -> list[float]:
    """Per truth the distance to the found target assigned to it (linear assignment), NaN
    for truths left without one (fewer found than there are)."""
    from scipy.optimize import linear_sum_assignment
    errors = [math.nan] * len(truths)
    if len(found):
        dist = np.linalg.norm(np.asarray(found)[None] - np.asarray(truths)[:, None], axis=2)
        for r, c in zip(*linear_sum_assignment(dist)):
            errors[r] = float(dist[r, c])
    return errors


def _warned(notes, closed_truth: bool = True) -> bool:
    """Did the answer warn? Not counted: the collinear notice, and where the truth is a plate
    the notice that the spots see only its front (it is about closed objects' centres; a box
    fitted with a poorly determined depth is warned about, whatever the truth)."""
    quiet = INFORMATIONAL if closed_truth else INFORMATIONAL + DEPTH_UNSEEN[:1]
    return any(not str(n).startswith(quiet) for n in notes)


def depth_unseen(notes) -> bool:
    return any(str(n).startswith(DEPTH_UNSEEN) for n in notes)


def _short(notes) -> str:
    return " | ".join(str(n).split(":")[0][:90] for n in notes)


def locate(hist, options: dict):
    """(found positions, warnings, seconds, model columns); an estimator that fails is a row,
    not a crash."""
    start = time.perf_counter()
    try:
        point = nl.locate_capture(hist, **options).points[0]
        found = [np.asarray(t.position, float) for t in point.location.targets]
        notes = list(point.warnings)
        model = fit_columns(point.location.targets)
    except Exception as exc:  # the table says so, the run goes on
        found, notes = [], [f"failed: {type(exc).__name__}: {str(exc)[:100]}"]
        model = fit_columns([])
    return found, notes, time.perf_counter() - start, model


def fit_columns(targets) -> dict:
    """The model selection's choice per target: the fitted shape's name ('-' for the paper's
    argmax) and, where closed shapes were tried, their BIC gain over the plate (the closed
    margin's evidence: docs/model-estimator.md)."""
    fits = [getattr(t, "fit", None) for t in targets]
    gains = [(f.diagnostics or {}).get("closed_bic_gain") if f is not None else None
             for f in fits]
    return {"fitted": " ".join(f.shape if f is not None else "-" for f in fits),
            "closed_gain": " ".join("-" if g is None else f"{g:.2f}" for g in gains)}


def describe(d: dict) -> dict:
    """The draw's columns: enough to read a row, and (family, index, master_seed) to re-run."""
    lay, m = d["layout"], d["mismatch"]
    kind = lay["kind"]
    if kind == "line":  # along x (the paper's) or along z: the search plane differs
        kind += "-z" if abs(math.cos(math.radians(lay["angle_deg"]))) < 0.5 else "-x"
    return {"family": d["family"], "sub": m["kind"] if m else d["targets"][0]["shape"],
            "index": d["index"], "master_seed": d["master_seed"], "layout": kind,
            "spots": len(lay["spots"]), "shapes": " ".join(t["shape"] for t in d["targets"]),
            "k_true": len(d["targets"]), "snr_db": d["snr_db"],
            "truths": " ; ".join(" ".join(f"{v:.3f}" for v in t["centre"])
                                 for t in d["targets"]),
            "mismatch": json.dumps(m, sort_keys=True) if m else "",
            "counting": json.dumps(d["counting"], sort_keys=True) if d.get("counting") else ""}


def run(d: dict, s: Settings) -> list[dict]:
    """Both estimators on the draw's one noisy frame: one row each (a crossing draw: its
    tracked sequence, one row, cross_run)."""
    if d["family"] == "crossings":
        from . import cross_run
        return cross_run.run(d, s)
    start = time.perf_counter()
    clean, sim_notes = scenes.simulate(d, s)
    frame = scenes.noisy(clean, d)
    sim_s = time.perf_counter() - start
    return located_rows(d, frame, {"sim_s": round(sim_s, 3), "sim_notes": _short(sim_notes)})


def located_rows(d: dict, frame, extra: dict) -> list[dict]:
    """One row per estimator of the draw's noisy `frame` (its errors, warnings, fitted shapes),
    with the columns of `extra` (how the frame was made) in each: `run`'s simulations, and
    scripts/mitransient_draws.py's renders of the same draws."""
    truths = np.array([t["centre"] for t in d["targets"]], float)
    rows, base = [], describe(d)
    closed_truth = any(t["shape"] in CLOSED_SHAPES for t in d["targets"])
    for label, options in estimators(d):
        found, notes, seconds, model = locate(frame, options)
        errors = matched_errors(found, truths)
        worst = max(errors) if not any(math.isnan(e) for e in errors) else math.nan
        rows.append({**base, "estimator": label, "k_found": len(found),
                     "error_m": round(worst, 5) if math.isfinite(worst) else math.nan,
                     "errors_m": " ".join(f"{e:.5f}" for e in errors),
                     "missed": sum(math.isnan(e) for e in errors),
                     "warned": _warned(notes, closed_truth),
                     "depth_unseen": depth_unseen(notes), "seconds": round(seconds, 3),
                     "warnings": _short(notes), **extra, **model})
    return rows
