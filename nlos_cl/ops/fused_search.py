"""fused_search (kernels/fused_search.cl): coarse-to-fine scoring (nlos_cl/search.py) with the
candidate selection, the refinement, the argmax and the 3 x 3 x 3 neighbourhood on the device:
two launches and one small read per frame, where the host-side search reads the coarse maps,
picks blocks, scores them and reads again.

fused_search(signal, dilated, stats, spots, laser, path0, inv_dpath, grid, factors, half,
log_mode, log_floor) -> (PATCH_RESULT,) floats laid out as argmax_patch's (nlos_cl/ops/
argmax_patch.py), with [4] = the number of candidate blocks. `dilated` = max_filter(signal,
half); `factors` = cells per block (fx, fy, fz); the coarse grid is `coarse_grid(grid,
factors)`. Every score is computed by score8 (kernels/score.h), so the best cell, its score and
its neighbours are bit-identical to scoring every cell with ellipse_score.
"""
from __future__ import annotations

import numpy as np

from ..core.constants import LOG_FLOOR
from ..core.grid import Grid
from . import ellipse_score as es
from .argmax_patch import PATCH_RESULT, result_of
from .base import Example, Operation, relative_error

SLACK = 1e-4  # relative: float32 rounding between a bound and a fine score (search.py)
WG = 64  # work-group size of the selection and the refinement
MAX_COARSE = 1 << 22  # coarse cells: beyond, the host-side search (one work group would crawl)
GROUPS_PER_UNIT = 4  # refinement work groups per compute unit
MAX_GROUPS = 1024


def coarse_grid(grid: Grid, factors) -> Grid:
    """The block centres of `grid` cut into blocks of `factors` cells (the last may be partial
    and its centre outside the grid)."""
    shape = tuple(-(-n // fa) for n, fa in zip(grid.shape, factors))
    origin = tuple(o + (fa - 1) / 2 * s for o, s, fa in zip(grid.origin, grid.step, factors))
    return Grid(origin, tuple(fa * s for s, fa in zip(grid.step, factors)), shape)


def centre_inside(grid: Grid, factors) -> np.ndarray:
    """(nz, ny, nx) of the coarse grid: whether each block's centre is a fine cell."""
    inside = [np.arange(-(-n // fa)) * fa + (fa - 1) // 2 < n
              for n, fa in zip(grid.shape, factors)]
    return inside[2][:, None, None] & inside[1][None, :, None] & inside[0][None, None, :]


def valid_counts(grid: Grid, factors) -> tuple:
    """Per axis, how many blocks have their centre inside the grid (always the first ones)."""
    return tuple((n - (fa - 1) // 2 + fa - 1) // fa for n, fa in zip(grid.shape, factors))


def numpy(signal, dilated, stats, spots, laser, path0, inv_dpath, grid, factors, half,
          log_mode=False, log_floor=LOG_FLOOR):
    fa = tuple(int(f) for f in factors)
    coarse = coarse_grid(grid, fa)
    common = (stats, spots, laser)
    exact = es.numpy(signal, *common, path0, inv_dpath, coarse, log_mode, log_floor)
    wide = np.asarray(path0, np.float64) - half / np.asarray(inv_dpath, np.float64)
    bound = es.numpy(dilated, *common, wide, inv_dpath, coarse, log_mode, log_floor)
    best = float(exact[centre_inside(grid, fa)].max())
    thr = best - SLACK * (abs(best) + (1.0 if log_mode else 0.0))
    iz, iy, ix = np.nonzero(bound >= thr)
    if len(ix) == 0:
        return result_of(None, -np.inf, np.full((3, 3, 3), np.nan))
    blocks = np.stack([ix, iy, iz], axis=1) * np.asarray(fa)
    args = (signal, *common, path0, inv_dpath, grid, log_mode, log_floor)
    scores = es.numpy(*args, blocks, fa)
    idx, inside = es.block_cells(grid, blocks, fa)
    nx, ny, _ = grid.shape
    flat = np.where(inside, (idx[..., 2] * ny + idx[..., 1]) * nx + idx[..., 0],
                    np.iinfo(np.int64).max)
    top = scores.max()
    win = int(np.argmin(np.where(scores == top, flat, np.iinfo(np.int64).max)))
    cell = tuple(int(v) for v in idx.reshape(-1, 3)[win])
    patch = es.numpy(*args, np.array([cell]) - 1, (3, 3, 3))[0]
    return result_of(cell, float(top), np.where(np.isfinite(patch), patch, np.nan), len(ix))


def _f4(p) -> np.ndarray:
    from ..device.runtime import float4
    return float4(p)


def _i4(v) -> np.ndarray:
    from ..device.runtime import int4
    return int4(v)


def refine_groups(rt) -> int:
    """Work groups of the refinement: GROUPS_PER_UNIT per compute unit (each a core of a CPU, a
    multiprocessor of a GPU), so every one has work and a few to balance uneven blocks."""
    return int(min(max(rt.device.max_compute_units, 1) * GROUPS_PER_UNIT, MAX_GROUPS))


def opencl(rt, signal, dilated, stats, spots, laser, path0, inv_dpath, grid, factors, half,
           log_mode=False, log_floor=LOG_FLOOR, out=None):
    from ..device.runtime import float4_rows
    n_det, n_bins = signal.shape
    if n_det > es.DET_TILE:
        raise ValueError(f"fused_search scores up to {es.DET_TILE} detectors in one pass")
    fa = tuple(int(f) for f in factors)
    coarse = coarse_grid(grid, fa)
    cx, cy, cz = coarse.shape
    if coarse.n_cells > MAX_COARSE:
        raise ValueError(f"fused_search: {coarse.n_cells} coarse cells, more than {MAX_COARSE}")
    defines = dict(N_DET=n_det, LOG_MODE=int(bool(log_mode)), LOG_FLOOR=f"{log_floor:.9e}f",
                   WG=WG, SLACK=f"{SLACK:.9e}f", PAIRED=es.paired(laser))  # both kernels
    path0, inv_dpath = np.asarray(path0, np.float64), np.asarray(inv_dpath, np.float64)
    axis = rt.constant(np.stack([path0, inv_dpath], axis=1))
    wide = rt.constant(np.stack([path0 - half / inv_dpath, inv_dpath], axis=1))
    spots_buf = rt.constant(float4_rows(spots))
    laser4 = rt.constant(float4_rows(np.asarray(laser).reshape(-1, 3)))
    groups = refine_groups(rt)
    exact, bound, blocks, value, where = rt.resource(("fused_search", coarse.n_cells), lambda: (
        rt.empty((cz, cy, cx)), rt.empty((cz, cy, cx)),
        rt.empty((1 + coarse.n_cells,), np.int32), rt.empty((groups,)),
        rt.empty((groups,), np.int32)))
    rt.run(rt.kernel("fused_search", "coarse_pair", **defines), (-(-cx // 8), cy, cz), signal,
           dilated, stats, spots_buf, laser4, axis, wide, np.int32(n_bins),
           np.int32(dilated.shape[1]), _f4(coarse.origin), _f4(coarse.step), np.int32(cx),
           np.int32(cy), _i4(valid_counts(grid, fa)), exact, bound)
    if out is None or isinstance(out, np.ndarray):  # (a host result: not a device buffer)
        out = rt.empty((PATCH_RESULT,))
    rt.run(rt.kernel("fused_search", "select_candidates", **defines), (WG,), exact, bound,
           _i4(coarse.shape), np.float32(1.0 if log_mode else 0.0), blocks, local_size=(WG,))
    fine = (signal, stats, spots_buf, laser4, axis, np.int32(n_bins), _f4(grid.origin),
            _f4(grid.step), _i4(grid.shape))
    rt.run(rt.kernel("fused_search", "refine_partial", **defines), (groups * WG,), *fine,
           _i4(fa), _i4(coarse.shape), blocks, value, where, local_size=(WG,))
    rt.run(rt.kernel("fused_search", "refine_finish", **defines), (WG,), *fine, blocks, value,
           where, np.int32(groups), out, local_size=(WG,))
    return out


# ---------------------------------------------------------------------------- examples

def _inputs(grid, factors, half_m=None, n_det=3, n_bins=200, target=(4.0, 2.0, 0.0),
            pairing=None):
    """ellipse_score's point-target rows, dilated by the path spread of a block."""
    from .max_filter import numpy as dilate
    base = es._point_target_inputs(grid, n_det=n_det, n_bins=n_bins, target=target,
                                   pairing=pairing)
    host = base(_Host())
    radius = 0.5 * np.sqrt(sum(((f - 1) * s) ** 2 for f, s in zip(factors, grid.step)))
    half = int(np.ceil(2 * (half_m or radius) * float(np.max(host[5])) + 0.01)) + 1
    dilated = dilate(host[0], half).astype(np.float32)

    def inputs(be, log_mode=False):
        args = base(be, log_mode)
        return (args[0], be.from_numpy(dilated), *args[1:7], factors, half, log_mode, args[8])
    return inputs


class _Host:
    @staticmethod
    def from_numpy(a):
        return np.asarray(a)


def _same_cell(device, twin) -> float:
    """The same best cell (else inf); then the relative error of score and neighbours, NaN
    exactly where the twin has NaN."""
    device, twin = np.asarray(device, np.float64), np.asarray(twin, np.float64)
    if not np.array_equal(device[:3], twin[:3]) or not np.array_equal(
            np.isnan(device[8:]), np.isnan(twin[8:])):
        return float("inf")
    keep = np.r_[3, 8 + np.flatnonzero(~np.isnan(twin[8:]))]
    return relative_error(device[keep], twin[keep])


def examples(size):
    plane = Grid((3.7, 1.9, 0.0), (0.02, 0.02, 0.02), (23, 13, 1))  # partial blocks, edge centres
    edge = Grid((4.0, 2.0, 0.0), (0.02, 0.02, 0.02), (21, 11, 1))  # the best cell on the edge
    volume = Grid((3.85, 1.9, -0.06), (0.02, 0.03, 0.04), (17, 9, 5))
    wide = Grid((3.6, 1.6, 0.0), (0.01, 0.01, 0.01), (40, 30, 1))  # 9-cell blocks: 2 float8s
    cases = [("plane, partial blocks", plane, (5, 5, 1)), ("best cell on the grid's edge", edge,
                                                           (3, 3, 1)),
             ("volume, blocks of 3x3x3", volume, (3, 3, 3)),
             ("blocks of 9 cells per row", wide, (9, 9, 1)),
             ("confocal volume, blocks of 3x3x3", volume, (3, 3, 3), "confocal"),
             ("paired plane, partial blocks", plane, (5, 5, 1), "paired")]
    if size != "tiny":
        big = Grid.from_ranges(x=(2.0, 6.0), y=(0.5, 4.0), step_m=0.01)
        cases.append(("400x350 plane, blocks of 5", big, (5, 5, 1)))
    out = []
    for label, grid, fa, *pairing in cases:
        inputs = _inputs(grid, fa, n_bins=2000 if size != "tiny" else 400,
                         pairing=pairing[0] if pairing else None)
        out += [Example(f"{label}, product", inputs, 1e-3, _same_cell),
                Example(f"{label}, log", (lambda i: lambda be: i(be, True))(inputs), 3e-3,
                        _same_cell)]
    return out


OP = Operation(
    "fused_search", "fused_search", opencl, numpy, examples,
    tolerance_note="the same best cell exactly; its score and neighbours within ellipse_score's "
    "tolerances (1e-3 of the peak in product mode, 3e-3 relative in log mode here).",
    bound="launches and one read (the cells are few)")
