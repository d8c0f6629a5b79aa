"""How positions and covariances appear in the JSON that nlos_cl prints and writes
(`nlos-cl locate --json`, `nlos-cl track --json`, the demo): in a capture's own frame (a signed
permutation of our axes, io.ytal.frames), rounded to what the method can tell."""
from __future__ import annotations

import numpy as np

from .ytal.frames import INTERNAL, CaptureFrame


def rounded(values) -> list:
    """Numbers as the JSON gives them: 5 decimals (0.01 mm)."""
    return [round(float(x), 5) for x in np.ravel(values)]


def vector_json(v, frame: CaptureFrame = INTERNAL) -> list:
    """A position (or velocity) of ours, in `frame`'s axes, rounded as the JSON gives it."""
    return rounded(frame.from_internal(v))


def covariance_in(cov, frame: CaptureFrame = INTERNAL) -> np.ndarray | None:
    """A 3 x 3 covariance (m^2) of ours in `frame`'s axes (m^T C m, internal = m @ file). The
    frame is a signed permutation, so the entries are moved, not mixed: an unobservable axis
    (infinite variance) stays infinite in its row and column only (a product would spread NaN)."""
    if cov is None:
        return None
    m = np.asarray(frame.matrix)
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
