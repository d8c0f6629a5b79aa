"""Rows read a block of bins at a time (forward/data.py's signal windows): the maxima of each
row's blocks in one pass, then the first or last bin above a level in one chosen block per row,
so that finding where a long row rises above a level reads it once, not bin by bin twice."""
from __future__ import annotations

import numpy as np


def block_maxima(rows, block: int) -> np.ndarray:
    """(D, ceil(n / block)) the maxima of each row's blocks of `block` bins (the last partial)."""
    n_bins = rows.shape[1]
    whole = n_bins // block * block
    parts = [rows[:, :whole].reshape(len(rows), -1, block).max(axis=2)]
    if whole < n_bins:
        parts.append(rows[:, whole:].max(axis=1, keepdims=True))
    return np.concatenate(parts, axis=1)


def first_above(rows, level, which, block: int, from_end: bool = False) -> np.ndarray:
    """Per row, the first (from_end: the last) bin above `level` in its block `which` (a block
    holding one; a row with none gets a bin of that block, which the caller replaces)."""
    n_bins = rows.shape[1]
    bins = which[:, None] * block + np.arange(block)[None, :]
    inside = bins < n_bins
    above = (np.take_along_axis(rows, np.minimum(bins, n_bins - 1), axis=1)
             > level[:, None]) & inside
    if from_end:
        return bins[:, 0] + block - 1 - above[:, ::-1].argmax(axis=1)
    return bins[:, 0] + above.argmax(axis=1)
