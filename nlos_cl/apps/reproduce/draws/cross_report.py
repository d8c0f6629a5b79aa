"""The `crossings` tables of `reproduce draws`, from its CSV rows only (cross_run writes
them): the share of draws that kept one track id per target after first_frame, the RMS
distribution (a draw's RMS: its worse target's; a target without a track in some frame, or a
tracker that failed, counts as infinite), frames/s, and the three targets. The draws that
lost an id are listed with what went wrong and what re-runs each alone."""
from __future__ import annotations

import math

import numpy as np

FAMILY = "crossings"
RMS_GOAL_M = 0.05
KEPT_GOAL = 0.95
FPS_GOAL = 5.0


def _bool(v) -> bool:
    return v is True or str(v) == "True"


def _float(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):  # a failed row's empty cell
        return math.nan


def _rms(rows) -> np.ndarray:
    e = np.array([_float(r["rms_m"]) for r in rows], float)
    return np.where(np.isnan(e), np.inf, e)


def _ranked(e: np.ndarray, q: float) -> float:
    """The q-quantile; where infinities are among the values, the rank's value (no blend)."""
    if np.isfinite(e).all():
        return float(np.percentile(e, q))
    return float(np.sort(e)[min(len(e) - 1, math.ceil(q / 100 * len(e)) - 1)])


def summary(rows) -> list[dict]:
    """One row for the family (empty without crossing rows)."""
    rows = [r for r in rows if r["family"] == FAMILY]
    if not rows:
        return []
    e = _rms(rows)
    fps = np.array([_float(r.get("frames_per_s")) for r in rows], float)
    fps = fps[np.isfinite(fps)]
    return [{"family": FAMILY, "sub": "all", "estimator": rows[0]["estimator"], "n": len(rows),
             "ids_kept": float(np.mean([_bool(r["ids_ok"]) for r in rows])),
             "rms_median_m": float(np.median(e)), "rms_p90_m": _ranked(e, 90),
             "rms_worst_m": float(e.max()), "rms_within_goal": float(np.mean(e <= RMS_GOAL_M)),
             "fps_median": float(np.median(fps)) if fps.size else math.nan,
             "fps_spread": float(np.percentile(fps, 75) - np.percentile(fps, 25))
             if fps.size else math.nan,
             "failed": sum(bool(r.get("failed")) for r in rows)}]


def _m(v: float) -> str:
    return "inf" if not math.isfinite(v) else f"{v:.4f}"


def goals(summ) -> list[dict]:
    """The crossing target as three rows (the draws' target-table form). 'RMS <= 0.05 m'
    is read per draw, held to the same >= 95 % of draws as the ids; frames/s as the median."""
    out = []
    for r in summ:
        if r["family"] != FAMILY:
            continue
        out += [{"goal": "crossings: one track id per target after frame 5", "n": r["n"],
                 "measured": f"{r['ids_kept']:.0%}", "target": ">= 95 % of draws",
                 "met": r["ids_kept"] >= KEPT_GOAL},
                {"goal": "crossings: RMS (worse target) <= 0.05 m", "n": r["n"],
                 "measured": f"{r['rms_within_goal']:.0%} (median {_m(r['rms_median_m'])} m)",
                 "target": ">= 95 % of draws", "met": r["rms_within_goal"] >= KEPT_GOAL},
                {"goal": "crossings: tracking frames/s (median)", "n": r["n"],
                 "measured": _fps(r).split(" ")[0], "target": ">= 5",
                 "met": bool(r["fps_median"] >= FPS_GOAL)}]
    return out


def _fps(r) -> str:
    """'median (IQR)' frames/s, or '-' where no draw was tracked to the end."""
    if not math.isfinite(r["fps_median"]):
        return "-"
    return f"{r['fps_median']:.2f} ({r['fps_spread']:.2f})"


def summary_table(summ) -> str:
    lines = ["| family | tracker | n | one id per target | RMS median (m) | RMS p90 (m) | "
             "RMS worst (m) | RMS <= 0.05 m | frames/s median (IQR) | failed |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in summ:
        lines.append(f"| {r['family']} | {r['estimator']} | {r['n']} | {r['ids_kept']:.0%} | "
                     f"{_m(r['rms_median_m'])} | {_m(r['rms_p90_m'])} | {_m(r['rms_worst_m'])} "
                     f"| {r['rms_within_goal']:.0%} | {_fps(r)} | {r['failed']} |")
    return "\n".join(lines)


def lost_table(rows, count: int = 10) -> str:
    """The draws that lost an id (the worst RMS first), with what the tracker did: births,
    tracks lost, merged frames (both targets nearest one track), frames with fewer than two
    measurements, swaps. Re-run one: draws.rerun("crossings", index, master_seed)."""
    rows = [r for r in rows if r["family"] == FAMILY and not _bool(r["ids_ok"])]
    lines = ["| index | master seed | layout | SNR (dB) | closest (m) | ids A | ids B | RMS (m) | "
             "births | lost | merged | < 2 measured | swaps | failed |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for i in np.argsort(-_rms(rows), kind="stable")[:count] if rows else []:
        r = rows[int(i)]
        lines.append(f"| {r['index']} | {r['master_seed']} | {r['layout']} | {r['snr_db']} | "
                     f"{r['closest_m']} | {r.get('ids_a', '')} | {r.get('ids_b', '')} | "
                     f"{_m(_rms([r])[0])} | {r.get('births', '')} | {r.get('lost', '')} | "
                     f"{r.get('merged_frames', '')} | {r.get('under_two_measured', '')} | "
                     f"{r.get('swaps', '')} | {str(r.get('failed', ''))[:60]} |")
    if len(lines) == 2:
        lines.append("| (none) |" + " |" * 13)
    return "\n".join(lines)


def how(fam: dict, failure_m: float) -> str:
    """What a crossing draw is and how its row is measured (from draws.yaml's crossings)."""
    r = lambda key, unit="": f"{fam[key][0]:g}-{fam[key][1]:g}{unit}"  # noqa: E731
    return (f"Each crossing draw: two upright plates (sides {r('plate_side_m', ' m')}) on "
            f"straight paths ({r('length_m', ' m')}, directions {r('turn_deg')} degrees "
            "apart) that cross at a random point of the region, each reaching it "
            f"{r('crossing_fraction')} of the way along, timed so that their centres come "
            f"within their half widths plus {r('gap_m', ' m')} (they never touch); "
            f"{fam['spots']} wall spots ({' or '.join(fam['layouts'])}); {fam['frames']} frames "
            f"at {fam['fps']:g} fps, {fam['dt_s'] * 1e12:g} ps bins, {fam['facet_m'] * 100:g} cm "
            "facets, AWGN at the draw's SNR. The frames are written as a sequence file and "
            f"tracked as `nlos-cl track FILE --targets 2` tracks it (its defaults: the model "
            f"fit warm-started from the tracks). From frame {fam['first_frame']} on, per target "
            "the nearest live track each frame: 'one id per target' when each target's nearest "
            "was one track throughout, and not the other's; the RMS of that track's 3-D "
            "distance (a draw's RMS: its worse target's; a frame without any track: "
            f"infinite); 'beyond' counts frames off by more than {failure_m:g} m. frames/s: "
            "Tracker.update after the first frame (make_tracker and the first frame, which "
            "builds the kernels, are timed apart), on shared cores: noisy. 'RMS <= 0.05 m' is "
            "read per draw, held to the ids' >= 95 % of draws.")
