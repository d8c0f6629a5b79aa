"""A scenario's answer scored against its truths. Found targets are matched to truths by linear
assignment on distance (nlos_cl.apps.locate.matched). A draw fails where the command refused or
crashed, where any lit truth is missed or found more than failure_m away, where the number of
targets found is wrong (fewer than the lit truths or more than all truths), or where a
shadowed truth is missed outside every shadow the answer declared (its JSON's "shadowed": the
truth's centre must lie where a found target hides it from the laser spot; a geometry check,
not words; a sequence declares none). A sequence is scored
on its frames from first_frame on: a mover's error is its median over the frames it is lit
(confirmed tracks matched to the movers frame by frame), and the number of targets found is
the most frequent number of confirmed tracks."""
from __future__ import annotations

import json
import math
from collections import Counter

import numpy as np

INF = math.inf


def describe(d: dict) -> dict:
    """The row's columns that say what the draw is."""
    truths = [o for o in d["objects"] if o["role"] != "furniture"]
    noise = d["noise"]
    photons = noise.get("photons") or {}
    return {"index": d["index"], "family": d["family"], "kind": kind(d),
            "shapes": " ".join(o["shape"] for o in truths),
            "furniture": " ".join(o["shape"] for o in d["objects"] if o["role"] == "furniture"),
            "truths": len(truths), "layout": d["layout"]["kind"],
            "spots": len(d["layout"]["spots"]),
            "snr_db": noise.get("snr_db", ""),
            "tdc_ps": round(photons["tdc_bin_s"] * 1e12, 1) if "tdc_bin_s" in photons else "",
            "n_pulses": photons.get("n_pulses", ""), "master_seed": d["master_seed"]}


def kind(d: dict) -> str:
    """The draw's sub-range, one word: where a family's failures gather."""
    f = d["family"]
    if f == "records":
        return d["record"]["kind"]
    if f == "walls":
        return d["wall"]["kind"]
    if f == "bins":
        ps = d["noise"]["photons"]["tdc_bin_s"] * 1e12
        return "16-100 ps" if ps < 100 else "100-500 ps" if ps < 500 else "0.5-1.5 ns"
    if f == "counts":
        return f"1e{math.floor(math.log10(d['noise']['photons']['n_pulses']))} pulses"
    if f in ("multi", "clutter"):
        n = sum(o["role"] != "furniture" for o in d["objects"])
        return f"K={n}"
    if f == "occluders":
        return "occluded " + d["objects"][0]["shape"]
    return d["objects"][0]["shape"]


def refused(stage: str, why: str) -> dict:
    return {"command": stage, "exit": "refused", "found": 0, "right_k": False,
            "error_m": INF, "errors_m": "", "lit": "", "failed": True,
            "why": f"{stage} refused", "warned": True, "in_declared_shadow": False, "said": why[:300]}


def _status(status) -> str:
    return "crash" if status == "crash" else str(status)


def _verdict(row: dict, cfg: dict, errors, lit, said, n_found, n_truths,
             excused=None) -> dict:
    """The failure rule (scenarios.yaml's failure_m) on per-truth errors (inf: missed), lit
    flags and, per truth, whether it lies in a shadow the answer declared (excused)."""
    excused = excused or [False] * len(errors)
    hidden = any(x for x, ok in zip(excused, lit) if not ok)
    lit_errors = [e for e, ok in zip(errors, lit) if ok]
    shadowed_missed = any(e > cfg["failure_m"] and not x
                          for e, ok, x in zip(errors, lit, excused) if not ok)
    n_lit = sum(lit)
    why = []
    if row["exit"] != "0":
        why.append("crashed" if row["exit"] == "crash" else f"exit {row['exit']}")
    worst = max(lit_errors, default=0.0)
    if worst > cfg["failure_m"]:
        why.append("lit target missed" if math.isinf(worst) else f"error {worst:.3f} m")
    right_k = n_lit <= n_found <= n_truths
    if not right_k:
        why.append(f"found {n_found} of {n_lit} lit")
    if shadowed_missed:
        why.append("shadowed target outside every declared shadow")
    row.update(found=n_found, right_k=right_k, error_m=round(worst, 4) if math.isfinite(worst)
               else INF, errors_m=" ".join(f"{e:.3f}" for e in errors),
               lit=" ".join("lit" if ok else "shadowed" for ok in lit), failed=bool(why),
               why="; ".join(why), warned=bool(said) and row["exit"] != "crash",
               in_declared_shadow=hidden, said=" | ".join(said)[:300])
    return row


def errors_of(positions, truths) -> list[float]:
    """Per truth, the distance to the found target assigned to it (inf where none is)."""
    from ...locate import matched
    positions = np.asarray(positions, float).reshape(-1, 3)
    out = [INF] * len(truths)
    for found, j in enumerate(matched(positions, np.asarray(truths, float))):
        if j is not None:
            out[j] = float(np.linalg.norm(positions[found] - truths[j]))
    return out


def locate(cfg: dict, status, stdout: str, said: list, truths_lit) -> dict:
    """A static capture's answer (`nlos-cl locate --json`): truths_lit is (the truths in the
    file's frame, each one's lit share)."""
    truths, shares = truths_lit
    lit = [s >= cfg["lit_share"] for s in shares]
    try:
        answer = json.loads(stdout) if stdout.strip() else {}
    except json.JSONDecodeError:
        answer = {}
    said = list(said) + [w for w in answer.get("warnings", []) or []  # the JSON's, once
                         if not any(s.endswith(w) for s in said)]
    found = [t["position"] for t in answer.get("targets", []) or []]
    row = {"exit": _status(status)}
    excused = [in_declared_shadow(t, answer) for t in truths]
    return _verdict(row, cfg, errors_of(found, truths), lit, said, len(found), len(truths),
                    excused)


def in_declared_shadow(point, answer: dict) -> bool:
    """Whether `point` (the file's frame) lies in a shadow the answer declared: behind a found
    target's box as its apex (the laser spot) sees it (localization.shadow.crosses)."""
    from ....localization.shadow import crosses
    for s in answer.get("shadowed") or []:
        box = s["box"]
        if crosses(s["apex"], point, np.asarray(box["centre"]), box["axes"], box["half_m"])[0]:
            return True
    return False


def track(cfg: dict, status, stdout: str, said: list, truths) -> dict:
    """A sequence's answer (`nlos-cl track --json`: one JSON object a frame); truths is
    {scored frame: (the movers in the file's frame, each one's lit share)}."""
    frames = {f.get("frame"): f for f in parse_lines(stdout)}
    share = cfg["lit_share"]
    per_mover, counts = None, []
    for k, (where, shares) in truths.items():
        f = frames.get(k, {})
        tracks = [t["position"] for t in f.get("tracks", []) if t.get("status") == "confirmed"
                  and not t.get("static")]
        counts.append(len(tracks))
        errors = errors_of(tracks, where)
        per_mover = per_mover or [[] for _ in errors]
        for m, (e, s) in enumerate(zip(errors, shares)):
            if s >= share:
                per_mover[m].append(e)
    per_mover = per_mover or []
    errors = [float(np.median(e)) if e else INF for e in per_mover]
    lit = [bool(e) for e in per_mover]
    n_found = Counter(counts).most_common(1)[0][0] if counts else 0
    row = {"exit": _status(status), "frames_right_k": round(
        sum(c == len(per_mover) for c in counts) / max(len(counts), 1), 3)}
    return _verdict(row, cfg, errors, lit, said, n_found, len(per_mover))


def parse_lines(text: str) -> list:
    """The JSON objects of a command's output, one a line (track's frames), skipping others."""
    frames = []
    for line in text.splitlines():
        line = line.strip()
        if line.startswith("{"):
            try:
                frames.append(json.loads(line))
            except json.JSONDecodeError:
                continue
    return frames
