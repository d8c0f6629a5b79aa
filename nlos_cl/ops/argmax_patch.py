"""argmax_patch (kernels/argmax.cl): argmax's first stage, then a final stage on the device that
also gathers the 3 x 3 x 3 scores around the best cell, so a frame's estimate costs one small
read instead of the first stage's candidates plus a read per plane of the neighbourhood.

argmax_patch(scores (nz, ny, nx)) -> (PATCH_RESULT,) floats: [ix, iy, iz, score, 0, 0, 0, 0,
then the 27 scores of cells (ix + dx, iy + dy, iz + dz), dz, dy, dx in -1..1, NaN outside the
grid]. The best cell is the first maximum (lowest flat index on ties), as `argmax`; ix = -1 when
no cell beats -inf. Indices are exact in float32 (grid axes have fewer than 2^24 cells).
"""
from __future__ import annotations

import numpy as np

from .argmax import WORK_ITEMS, opencl as argmax_opencl
from .base import Example, Operation

PATCH_RESULT = 8 + 27


def decode(result):
    """(index (ix, iy, iz) or None, score, header[4], patch (3, 3, 3) float64) of a result."""
    r = np.asarray(result, np.float64)
    index = None if r[0] < 0 else (int(r[0]), int(r[1]), int(r[2]))
    return index, float(r[3]), float(r[4]), r[8:8 + 27].reshape(3, 3, 3)


def result_of(index, score, patch, count=0.0):
    """The result layout from host values (the twins and the host fallback)."""
    out = np.zeros(PATCH_RESULT)
    out[:3] = (-1, 0, 0) if index is None else index
    out[3], out[4] = score, count
    out[8:] = np.asarray(patch, np.float64).reshape(-1)
    return out


def neighbourhood(read_rows, shape, index):
    """The 3 x 3 x 3 scores around index = (ix, iy, iz) on a grid of shape (nx, ny, nz), NaN
    outside it; read_rows(iz, iy0, iy1) gives one plane's rows (a host array, a device map)."""
    nx, ny, nz = shape
    ix, iy, iz = index
    patch = np.full((3, 3, 3), np.nan)
    y0, y1 = max(iy - 1, 0), min(iy + 2, ny)
    x0, x1 = max(ix - 1, 0), min(ix + 2, nx)
    for dz in (-1, 0, 1):
        if 0 <= iz + dz < nz:
            rows = np.asarray(read_rows(iz + dz, y0, y1))[:, x0:x1]
            patch[dz + 1, y0 - iy + 1:y1 - iy + 1, x0 - ix + 1:x1 - ix + 1] = rows
    return patch


def patch_of(score, index):
    """The 3 x 3 x 3 host scores (nz, ny, nx) around index = (ix, iy, iz), NaN outside."""
    nz, ny, nx = score.shape
    return neighbourhood(lambda z, a, b: score[z, a:b], (nx, ny, nz), index)


def numpy(score):
    score = np.asarray(score, np.float64)
    flat = int(np.argmax(score))
    value = float(score.reshape(-1)[flat])
    if not value > -np.inf:
        return result_of(None, value, np.full((3, 3, 3), np.nan))
    iz, rem = divmod(flat, score.shape[1] * score.shape[2])
    iy, ix = divmod(rem, score.shape[2])
    return result_of((ix, iy, iz), value, patch_of(score, (ix, iy, iz)))


def _host_fallback(rt, score):
    """A map in several slabs: argmax's own stages, then the rows of the neighbourhood."""
    flat, value = argmax_opencl(rt, score)
    nx, ny, nz = score.shape
    if flat < 0:
        return result_of(None, value, np.full((3, 3, 3), np.nan))
    iz, rem = divmod(flat, nx * ny)
    iy, ix = divmod(rem, nx)
    patch = neighbourhood(lambda z, a, b: score.rows(rt.queue, z, a, b), score.shape,
                          (ix, iy, iz))
    return result_of((ix, iy, iz), value, patch).astype(np.float32)


def opencl(rt, score, out=None):
    """`score`: a (nz, ny, nx) device array or a ScoreMap; a map in one slab stays on the
    device (two launches, no read); one in several slabs is read as argmax does."""
    from .ellipse_score import ScoreMap
    if not isinstance(score, ScoreMap):
        score = ScoreMap.whole(score)
    if len(score.slabs) != 1:
        return _host_fallback(rt, score)
    slab = score.slabs[0][1]
    nx, ny, nz = score.shape
    n_cells = nx * ny * nz
    items = min(WORK_ITEMS, n_cells)
    per_item = -(-n_cells // items)
    value, index = rt.resource(("argmax_patch", items), lambda: (
        rt.empty((items,)), rt.empty((items,), np.int32)))
    rt.run(rt.kernel("argmax", "argmax_partial"), (items,), slab, np.int32(n_cells),
           np.int32(per_item), value, index)
    if out is None or isinstance(out, np.ndarray):  # (a host result from the fallback)
        out = rt.empty((PATCH_RESULT,))
    rt.run(rt.kernel("argmax", "argmax_patch"), (9,), value, index, np.int32(items), slab,
           np.int32(nx), np.int32(ny), np.int32(nz), out)
    return out


def _exact(device, twin) -> float:
    """0 when every value agrees exactly (NaN where NaN), else 1."""
    return 0.0 if np.array_equal(np.asarray(device), np.asarray(twin), equal_nan=True) else 1.0


def examples(size):
    rng = np.random.default_rng(7)
    edge = rng.random((1, 7, 9)).astype(np.float32)
    edge[0, 0, 8] = 2.0  # the best cell in a corner: the patch is NaN past two edges
    tie = np.zeros((3, 5, 6), np.float32)
    tie[1, 2, 3] = tie[2, 4, 5] = 3.0  # a tie: the lower flat index wins; a volume patch
    many = rng.random((2, 30, 50)).astype(np.float32)  # 3000 cells: 3 per first-stage item
    cases = [("best cell in a corner", edge), ("a tie in a volume", tie), ("3000 cells", many)]
    if size != "tiny":
        cases.append(("180,000 cells", rng.random((3, 200, 300)).astype(np.float32)))
    return [Example(label, (lambda a: lambda be: (be.from_numpy(a),))(arr), 0.0, _exact)
            for label, arr in cases]


OP = Operation("argmax_patch", "argmax", opencl, numpy, examples,
               tolerance_note="exact: index, value and the 27 neighbours must be identical "
               "(copies of the map's own values).", bound="launches and one read")
