"""Photon counts recorded through a gate: bins where the detector was off are not
measurements. CC-SOCR's records ("bins before ~300 are gated to zero", its README) hold
exact zeros around a block of ~800-1,300 counts a bin; read as measured zeros, every model
with a background above 0 misses them by its whole level (a plate's deviance per degree of
freedom ~450 on 3 points, ~60 with the gate's zeros left out).

A row's edge is a gate where the run of zeros outside its nonzero support meets, inside it,
GATE_EDGE_BINS bins that all hold at least GATE_LEVEL counts: a Poisson bin of mean >= 10
next to a zero one has probability e^-10 of being that zero, while light that truly starts
there (a return on a dark record) rises through small counts first. Rows whose support is
shorter than GATE_MIN_SUPPORT bins are left as they are: with bins as wide as the pulse
(1-1.5 ns TDCs) a return alone fills a bin or two from nothing.
"""
from __future__ import annotations

import numpy as np

GATE_LEVEL = 10.0  # counts: each of the bins inside a gate edge at least this
GATE_EDGE_BINS = 8  # bins inside an edge that must all hold GATE_LEVEL
GATE_MIN_SUPPORT = 16  # bins of nonzero support a gated row has at least
ROWS_A_PASS = 256


def gate_bounds(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first, last) record bin of each row's gate, inclusive: the row's nonzero support at
    an edge that is a gate (module docstring), else the record's own end."""
    counts = np.asarray(counts)
    d, n = counts.shape
    first, last = np.zeros(d, dtype=np.int64), np.full(d, n - 1, dtype=np.int64)
    lo, hi = first.copy(), last.copy()
    # only rows that end in a zero can be gated (a record with ambient light reads no more)
    rows = np.flatnonzero((counts[:, 0] == 0) | (counts[:, -1] == 0))
    for at in range(0, len(rows), ROWS_A_PASS):  # bounded temporaries on a SPAD record
        part = rows[at:at + ROWS_A_PASS]
        lit = counts[part] > 0
        lo[part] = lit.argmax(axis=1)
        hi[part] = n - 1 - lit[:, ::-1].argmax(axis=1)
    any_lit = counts[np.arange(d), lo] > 0  # argmax of an all-zero row is 0, and unlit
    rows = rows[any_lit[rows] & (hi[rows] - lo[rows] + 1 >= GATE_MIN_SUPPORT)]
    inside = np.arange(GATE_EDGE_BINS)  # the support holds >= GATE_MIN_SUPPORT of them
    after = counts[rows[:, None], lo[rows, None] + inside].min(axis=1) >= GATE_LEVEL
    before = counts[rows[:, None], hi[rows, None] - inside].min(axis=1) >= GATE_LEVEL
    starts, ends = rows[after & (lo[rows] > 0)], rows[before & (hi[rows] < n - 1)]
    first[starts], last[ends] = lo[starts], hi[ends]
    return first, last


def in_gate(idx: np.ndarray, bounds) -> np.ndarray:
    """Which record bins idx (D, m) lie inside their row's gate (`gate_bounds`)."""
    first, last = bounds
    return (idx >= first[:, None]) & (idx <= last[:, None])


def gated_report(bounds, n_bins: int) -> dict | None:
    """What a capture's `processing` says of its gates: the rows gated, and the median first
    and last bin of their gates; None where no row is."""
    first, last = bounds
    rows = (first > 0) | (last < n_bins - 1)
    if not rows.any():
        return None
    return {"rows": int(rows.sum()), "of": int(len(first)),
            "first_bin_median": int(np.median(first[rows])),
            "last_bin_median": int(np.median(last[rows])),
            "note": "bins outside a gate are not measurements: the fit leaves them out, the "
                    "filter reads them filled with the gate's edge level"}


def ungated(counts: np.ndarray, bounds=None) -> np.ndarray | None:
    """A copy of `counts` with each gate's outside filled with the level just inside its edge
    (the mean of GATE_EDGE_BINS bins), for the Gauss filter's input only: filtered, a gate's
    edge is a step of the whole ambient level, which the detection and the argmax read as a
    return (a gated plate at 271 counts a bin: a box 0.7 m off). None where no row is gated.
    The fit reads the counts as recorded, without the gated bins (`gate_bounds`)."""
    first, last = gate_bounds(counts) if bounds is None else bounds
    n = counts.shape[1]
    rows = np.flatnonzero((first > 0) | (last < n - 1))
    if not rows.size:
        return None
    out = np.array(counts, dtype=np.float64)
    inside, bins = np.arange(GATE_EDGE_BINS), np.arange(n)[None, :]
    for at in range(0, len(rows), ROWS_A_PASS):  # bounded temporaries on a SPAD record
        r = rows[at:at + ROWS_A_PASS]
        a, b = first[r, None], last[r, None]
        # each gated row's outside: the mean of the GATE_EDGE_BINS bins inside its edge (an
        # end that is no gate has an empty mask)
        lead = out[r[:, None], a + inside].mean(axis=1, keepdims=True)
        tail = out[r[:, None], b - inside].mean(axis=1, keepdims=True)
        out[r] = np.where(bins < a, lead, np.where(bins > b, tail, out[r]))
    return out
