"""How positions and covariances appear in the JSON that nlos_cl prints and writes
(`nlos-cl locate --json`, `nlos-cl track --json`, the demo): in a capture's own frame (a rigid
transform of ours, io.ytal.frames), rounded to what the method can tell."""
from __future__ import annotations

import numpy as np

from .ytal.frames import INTERNAL, CaptureFrame


def rounded(values) -> list:
    """Numbers as the JSON gives them: 5 decimals (0.01 mm)."""
    return [round(float(x), 5) for x in np.ravel(values)]


def vector_json(v, frame: CaptureFrame = INTERNAL, direction: bool = False) -> list:
    """A position (direction=True: a velocity, rotated only) of ours, in `frame`'s axes,
    rounded as the JSON gives it."""
    return rounded(frame.direction_from_internal(v) if direction else frame.from_internal(v))


def covariance_in(cov, frame: CaptureFrame = INTERNAL) -> np.ndarray | None:
    """A 3 x 3 covariance (m^2) of ours in `frame`'s axes (m^T C m, internal = m @ file). A
    signed permutation moves the entries, not mixes them: an unobservable axis (infinite
    variance) stays infinite in its row and column only (a product would spread NaN); a
    rotation mixes them, and every file axis an infinite one reaches is infinite."""
    if cov is None:
        return None
    m = np.asarray(frame.matrix)
    if not frame.is_permutation:
        c = np.asarray(cov, dtype=np.float64)
        bad = ~np.isfinite(np.diag(c))
        out = m.T @ np.where(np.isfinite(c), c, 0.0) @ m
        reach = np.abs(m[bad]).max(axis=0) > 1e-12 if bad.any() else np.zeros(3, bool)
        out[reach, :], out[:, reach] = np.nan, np.nan
        out[reach, reach] = np.inf
        return out
    axis = np.abs(m).argmax(axis=0)  # file axis i is internal axis axis[i]
    sign = m[axis, np.arange(3)]
    return np.asarray(cov, dtype=np.float64)[np.ix_(axis, axis)] * np.outer(sign, sign)


def covariance_json(cov, frame: CaptureFrame = INTERNAL):
    """covariance_in as JSON: 6 significant digits, an infinite variance null (JSON has no
    infinity)."""
    out = covariance_in(cov, frame)
    if out is None:
        return None
    return [[float(f"{v:.6g}") if np.isfinite(v) else None for v in row] for row in out]


def entry_internal(entry: dict, frame: CaptureFrame) -> dict:
    """A located entry's truths and targets (JSON, `frame`'s axes) in our axes, covariances
    left out: what a figure of a map along our axes draws (a fitted wall's rotated frame)."""
    truths = entry.get("truths") or ([entry["truth"]] if entry.get("truth") else [])
    return {"truths": [list(frame.to_internal(t)) for t in truths],
            "targets": [{"position": list(frame.to_internal(t["position"])), "covariance": None}
                        for t in entry.get("targets", [])]}
