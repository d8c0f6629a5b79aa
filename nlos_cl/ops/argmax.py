"""argmax (kernels/argmax.cl): the first maximum of a score map (lowest flat index on ties, on
every device). argmax(scores) -> (flat index, value). On the device a first stage leaves one
candidate per work item; the host picks among those few (and among slabs)."""
from __future__ import annotations

import numpy as np

from .base import Example, Operation

WORK_ITEMS = 1024  # work items in the first stage


def numpy(score):
    score = np.asarray(score)
    flat = int(np.argmax(score))
    return flat, float(score.reshape(-1)[flat])


def opencl(rt, score, out=None):
    from .ellipse_score import ScoreMap
    if not isinstance(score, ScoreMap):
        score = ScoreMap.whole(score)
    kern = rt.kernel("argmax", "argmax_partial")
    best = (-1, -np.inf)
    for start, slab in score.slabs:
        n_cells = slab.size
        items = min(WORK_ITEMS, n_cells)
        per_item = -(-n_cells // items)
        best_value, best_index = rt.empty((items,)), rt.empty((items,), np.int32)
        rt.run(kern, (items,), slab, np.int32(n_cells), np.int32(per_item), best_value,
               best_index)
        values, indices = best_value.get(rt.queue), best_index.get(rt.queue)
        w = int(np.argmax(values))  # first maximum within the slab
        if values[w] > best[1]:  # strict: an earlier slab wins ties
            best = (start * score.cells_per_step + int(indices[w]), float(values[w]))
    return best


def _exact(device, twin) -> float:
    """0 when index and value agree exactly, else 1."""
    return 0.0 if tuple(np.ravel(device)) == tuple(np.ravel(twin)) else 1.0


def examples(size):
    tie = np.zeros((1, 7, 9), np.float32)
    tie[0, 2, 3] = tie[0, 5, 8] = 3.0  # a tie: the lower flat index must win
    tie[0, 6, 0] = 2.0
    # 1500 cells: 2 per work item, so the last work items get empty ranges.
    many = np.random.default_rng(5).random((1, 30, 50)).astype(np.float32)
    big = np.random.default_rng(6).random((3, 200, 300)).astype(np.float32)
    cases = [("a tie: the first maximum wins", tie), ("1500 cells", many)]
    if size != "tiny":
        cases.append(("180,000 cells", big))
    return [Example(label, (lambda a: lambda be: (be.from_numpy(a),))(arr), 0.0, _exact)
            for label, arr in cases]


OP = Operation("argmax", "argmax", opencl, numpy, examples,
               tolerance_note="exact: index and value must be identical (ties included).",
               bound="bandwidth")
