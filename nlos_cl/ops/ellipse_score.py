"""ellipse_score (kernels/ellipse_score.cl): paper Section 2.1 and 3.2.

A grid cell c lies on detector d's ellipse of hidden path |c - O| + |c - spot_d|; its
likelihood under d is the filtered signal at that path (linear interpolation between bin
centres, 0 outside the record, negatives clipped), over the row's maximum. The joint likelihood
is the product over detectors, or the sum of log(max(v, log_floor)) in log mode.

Signature (both backends): ellipse_score(signal, stats, spots, laser, path0, inv_dpath, grid,
log_mode, log_floor) -> (nz, ny, nx) scores (a `ScoreMap` on the device). laser: (3,), every
detector's laser spot, or (n_det, 3), each detector's own (paired and confocal captures: the
kernels' -D PAIRED=1). path0: hidden path at the centre of bin 0 per detector; inv_dpath: bins
per metre of path.
"""
from __future__ import annotations

import numpy as np

from ..core.constants import LOG_FLOOR
from ..core.histograms import laser_spots_of
from .base import Example, Operation, relative_error

CELLS_PER_ITEM = 8  # float8 arithmetic along x (ellipse_score.cl)
DET_TILE = 16  # detectors per launch: their rows stay in cache while every cell reads them


class ScoreMap:
    """A grid's scores on the device, in one or more slabs of planes (or of rows)."""

    def __init__(self, shape, by_plane, slabs):
        self.shape = shape  # (nx, ny, nz)
        self.by_plane = by_plane
        self.slabs = slabs  # [(first plane or row, device array)]
        nx, ny, _ = shape
        self.cells_per_step = nx * ny if by_plane else nx

    @classmethod
    def whole(cls, array) -> "ScoreMap":
        """A (nz, ny, nx) device array as a one-slab map."""
        nz, ny, nx = array.shape
        return cls((nx, ny, nz), True, [(0, array)])

    @property
    def size(self) -> int:
        return self.shape[0] * self.shape[1] * self.shape[2]

    def get(self, queue) -> np.ndarray:
        return np.concatenate([slab.get(queue) for _, slab in self.slabs],
                              axis=0 if self.by_plane else 1)

    def rows(self, queue, iz, iy0, iy1) -> np.ndarray:
        """Scores of plane iz, rows iy0..iy1 (exclusive), as float64."""
        parts = []
        for start, slab in self.slabs:
            if self.by_plane:
                if start <= iz < start + slab.shape[0]:
                    return slab[iz - start, iy0:iy1].get(queue).astype(np.float64)
            else:
                lo, hi = max(iy0, start), min(iy1, start + slab.shape[1])
                if lo < hi:
                    parts.append(slab[0, lo - start:hi - start].get(queue))
        return np.concatenate(parts).astype(np.float64)


def _score_cells(cells, signal, stats, spots, laser, path0, inv_dpath, log_mode, log_floor):
    """The joint likelihood of (n, 3) cell centres, float64."""
    lasers = laser_spots_of(laser, len(spots))
    signal, stats = np.asarray(signal, np.float64), np.asarray(stats, np.float64)
    n_bins = signal.shape[1]
    joint = np.zeros(len(cells)) if log_mode else np.ones(len(cells))
    for d in range(signal.shape[0]):  # a loop over detectors; cells are vectorized
        r1 = np.linalg.norm(cells - lasers[d], axis=1)
        u = (r1 + np.linalg.norm(cells - spots[d], axis=1) - path0[d]) * inv_dpath[d]
        i0 = np.floor(u).astype(np.int64)
        t = u - i0
        padded = np.concatenate([[0.0], signal[d], [0.0]])  # 0 outside the record
        v0 = padded[np.clip(i0, -1, n_bins) + 1]
        v1 = padded[np.clip(i0 + 1, -1, n_bins) + 1]
        peak = stats[d, 0]
        v = np.maximum(v0 + t * (v1 - v0), 0.0) * (1.0 / peak) if peak > 0 else np.zeros_like(u)
        joint = joint + np.log(np.maximum(v, log_floor)) if log_mode else joint * v
    return joint


def paired(laser) -> int:
    """The kernels' PAIRED option: 1 where each detector has its own laser spot."""
    return int(np.asarray(laser).size > 3)


def block_cells(grid, blocks, tile):
    """Grid indices (n_blocks, tz, ty, tx, 3) of the tiles' cells, and whether each is inside."""
    tx, ty, tz = tile
    jz, jy, jx = np.meshgrid(np.arange(tz), np.arange(ty), np.arange(tx), indexing="ij")
    idx = np.asarray(blocks, np.int64)[:, None, None, None, :] + np.stack([jx, jy, jz], -1)
    return idx, np.all((idx >= 0) & (idx < np.asarray(grid.shape)), axis=-1)


def numpy(signal, stats, spots, laser, path0, inv_dpath, grid, log_mode=False,
          log_floor=LOG_FLOOR, blocks=None, tile=None):
    """blocks, tile: score only tiles of tile = (tx, ty, tz) cells whose first cells are the
    (n, 3) grid indices `blocks`, as (n, tz, ty, tx); cells outside the grid get -inf."""
    args = (signal, stats, spots, laser, path0, inv_dpath, log_mode, log_floor)
    if blocks is None:
        joint = _score_cells(grid.cell_centres().reshape(-1, 3), *args)
        return joint.reshape(grid.shape[2], grid.shape[1], grid.shape[0])
    idx, inside = block_cells(grid, blocks, tile)
    cells = np.asarray(grid.origin) + idx * np.asarray(grid.step)
    joint = _score_cells(cells.reshape(-1, 3), *args).reshape(inside.shape)
    return np.where(inside, joint, -np.inf)


def detector_tiles(n_det: int) -> list[tuple[int, int]]:
    """(first, stop) detectors per launch: one launch up to DET_TILE detectors, else tiles."""
    return [(d, min(d + DET_TILE, n_det)) for d in range(0, n_det, DET_TILE)]


def _tiled(rt, n_det, log_mode, log_floor, launch, is_paired):
    for d0, d1 in detector_tiles(n_det):
        kern = rt.kernel("ellipse_score", launch.__name__, N_DET=d1 - d0,
                         LOG_MODE=int(bool(log_mode)), LOG_FLOOR=f"{log_floor:.9e}f",
                         PAIRED=is_paired)
        launch(kern, np.int32(d0), np.int32(d0 > 0))


def opencl(rt, signal, stats, spots, laser, path0, inv_dpath, grid, log_mode=False,
           log_floor=LOG_FLOOR, blocks=None, tile=None, out=None):
    """`out`: a ScoreMap from an earlier call on the same grid, reused (a plan's buffer)."""
    from ..device.runtime import float4, float4_rows
    nx, ny, nz = grid.shape
    n_det, n_bins = signal.shape
    is_paired = paired(laser)
    # float32 path lengths of ~10 m round to ~1e-6 m: ~0.003 of a 1 ps (0.3 mm) bin.
    axis = rt.constant(np.stack([path0, inv_dpath], axis=1))
    spots_buf = rt.constant(float4_rows(spots))
    lasers_buf = rt.constant(float4_rows(np.asarray(laser).reshape(-1, 3)))
    common = (signal, stats, spots_buf, lasers_buf, axis, np.int32(n_bins),
              float4(grid.origin), float4(grid.step))
    if blocks is not None:
        return _blocks(rt, common, grid, blocks, tile, n_det, log_mode, log_floor, is_paired)
    by_plane = nz > 1  # slabs of whole planes, or of rows of the single plane
    n, row_bytes = (nz, 4 * nx * ny) if by_plane else (ny, 4 * nx)
    groups = rt.groups(n, row_bytes, "a row of the score map")
    if out is None or [a0 for a0, _ in out.slabs] != [a0 for a0, _ in groups]:
        out = ScoreMap(grid.shape, by_plane, [
            (a0, rt.empty((a1 - a0, ny, nx) if by_plane else (1, a1 - a0, nx)))
            for a0, a1 in groups])
    for a0, score in out.slabs:
        planes, rows = score.shape[0], score.shape[1]

        def ellipse_score(kern, det0, acc):
            rt.run(kern, (-(-nx // CELLS_PER_ITEM), rows, planes), *common, np.int32(nx),
                   np.int32(rows), np.int32(0 if by_plane else a0),
                   np.int32(a0 if by_plane else 0), det0, acc, score)
        _tiled(rt, n_det, log_mode, log_floor, ellipse_score, is_paired)
    return out


def _blocks(rt, common, grid, blocks, tile, n_det, log_mode, log_floor, is_paired):
    from pyopencl import cltypes
    tx, ty, tz = (int(v) for v in tile)
    first = np.zeros((len(blocks), 4), np.int32)
    first[:, :3] = blocks
    first_buf = rt.constant(first, np.int32)
    out = rt.empty((len(blocks), tz, ty, tx))

    # A CPU device gets a fixed local size of one item: PoCL builds a kernel anew for each
    # local size it picks, and it picks it from the global size, which here follows the block
    # count or a tracker's window, frame by frame. On the consumer walk's first run (a cold
    # kernel cache) that was 165 builds of this kernel, 48 s against 22.6 s now (the argmax's
    # track 19.4 -> 10.9 s); warm, the walk, the crossing tracker and the SPAD search timed
    # alike (interleaved), the scores the same cell by cell. A GPU keeps its driver's choice.
    local = (1, 1, 1) if rt.on_cpu else None
    items = -(-tx // CELLS_PER_ITEM)

    def ellipse_score_blocks(kern, det0, acc):
        rt.run(kern, (items, ty, len(blocks) * tz), *common,
               cltypes.make_int4(*grid.shape, 0), first_buf, cltypes.make_int4(tx, ty, tz, 0),
               det0, acc, out, local_size=local)
    _tiled(rt, n_det, log_mode, log_floor, ellipse_score_blocks, is_paired)
    return out


# ---------------------------------------------------------------------------- examples

def _log_error(device, twin) -> float:
    """Log mode: absolute error (log units) where the twin is above 1e-4 per detector."""
    lit = twin > 3 * np.log(1e-4)
    return float(np.abs(device - twin)[lit].max()) if lit.any() else float("inf")


def _point_target_inputs(grid, n_det=3, n_bins=3000, dt_m=3e-3, target=(4.0, 2.0, 0.0),
                         pairing=None):
    """Smooth, filtered-looking rows: a Gaussian of 10 cm around the path of a point target
    (the width of a filtered signal) and a negative stretch at the start of the record (the
    kernel clips it to 0); path0 puts the record around the target's paths. pairing: None (one
    laser at the origin), "confocal" (each detector its own laser spot, the same point) or
    "paired" (each its own laser spot elsewhere on the wall)."""
    if n_det <= 8:  # the paper's line, slightly staggered in height
        spots = np.array([[-0.5 - 0.5 * d, 0.0, 0.1 * (d % 3 - 1)] for d in range(n_det)])
    else:  # a square SPAD-array patch
        side = int(np.ceil(np.sqrt(n_det)))
        spots = np.array([[x, 0.0, z] for x in np.linspace(-1.6, -0.4, side)
                          for z in np.linspace(-0.6, 0.6, side)])[:n_det]
    laser, p = np.zeros(3), np.asarray(target)
    if pairing == "confocal":
        laser = spots.copy()
    elif pairing == "paired":
        laser = spots[::-1] + np.array([0.3, 0.0, 0.05])
    path = np.linalg.norm(p - laser, axis=-1) + np.linalg.norm(p - spots, axis=1)
    path0 = path - 0.5 * n_bins * dt_m
    centres = path0[:, None] + dt_m * np.arange(n_bins)[None, :]
    rows = np.exp(-0.5 * ((centres - path[:, None]) / 0.1) ** 2).astype(np.float32)
    rows[:, :n_bins // 20] = -0.05
    stats = np.stack([rows.max(axis=1), np.mean(rows.astype(np.float64) ** 2, axis=1)], axis=1)
    inv = np.full(n_det, 1.0 / dt_m)

    def inputs(backend, log_mode=False):
        return (backend.from_numpy(rows), backend.from_numpy(stats), spots, laser, path0, inv,
                grid, log_mode, LOG_FLOOR)
    return inputs


def _bench_examples():
    from ..core.grid import Grid
    out = []
    for n in (601, 2048):
        grid = Grid((0.0, 0.01, 0.0), (6 / (n - 1), 6 / n, 0.01), (n, n, 1))
        out.append(Example(f"plane: {n}x{n} cells x 3 det", _point_target_inputs(grid), 1e-3,
                           work=3 * grid.n_cells, unit="cell-detector"))
    spad_grid = Grid((2.0, 0.5, 0.0), (4 / 512, 4 / 512, 0.01), (512, 512, 1))
    spad = _point_target_inputs(spad_grid, n_det=1024, n_bins=4096)
    out.append(Example("SPAD 32x32: 512x512 cells x 1024 det (log)", lambda be: spad(be, True),
                       3e-3, _log_error, work=1024 * spad_grid.n_cells, unit="cell-detector",
                       twin_inputs=lambda be: _point_target_inputs(spad_grid, 64, 4096)(be, True),
                       twin_fraction=64 / 1024))
    vol = Grid((2.0, 0.5, -1.0), (4 / 256, 4 / 256, 2 / 256), (256, 256, 256))
    out.append(Example("volume: 256x256x256 cells x 3 det", _point_target_inputs(vol), 1e-3,
                       work=3 * vol.n_cells, unit="cell-detector"))
    return out


def _masked(error):
    """Compare where the twin is finite; cells outside the grid must be -inf on both sides."""
    def compare(device, twin):
        inside = np.isfinite(twin)
        if not np.array_equal(inside, np.isfinite(device)):
            return float("inf")
        return error(device[inside], twin[inside])
    return compare


def _both_modes(label, inputs, masked=False, **kw):
    product, log = (_masked(relative_error), _masked(_log_error)) if masked else (
        relative_error, _log_error)
    return [Example(f"{label}, product", inputs, 1e-3, product, **kw),
            Example(f"{label}, log", lambda be: inputs(be, True), 3e-3, log, **kw)]


def _with_blocks(inputs, blocks, tile):
    """The same inputs, scoring only tiles of cells (coarse-to-fine refinement)."""
    return lambda be, log_mode=False: inputs(be, log_mode) + (np.asarray(blocks), tile)


def examples(size):
    from ..core.grid import Grid
    if size == "bench":
        return _bench_examples()
    if size == "check":
        plane = Grid.from_ranges(x=(0, 6), y=(0.01, 6), step_m=0.02)
        volume = Grid((3.0, 1.0, -0.5), (0.05, 0.05, 0.05), (41, 41, 21))
        spad = Grid((3.0, 1.0, 0.0), (0.02, 0.02, 0.02), (101, 101, 1))
        return (_both_modes("plane 301x300", _point_target_inputs(plane))
                + _both_modes("volume 41x41x21", _point_target_inputs(volume))
                + _both_modes("100 detectors in tiles", _point_target_inputs(spad, n_det=100,
                                                                          n_bins=1000))
                + _both_modes("volume tiles of 11x11x11 cells", _with_blocks(
                    _point_target_inputs(volume), [[0, 0, 0], [33, 33, 11], [16, 20, 5]],
                    (11, 11, 11)), masked=True)
                + _both_modes("plane 301x300, confocal", _point_target_inputs(
                    plane, n_det=5, pairing="confocal"))
                + _both_modes("volume 41x41x21, paired", _point_target_inputs(
                    volume, n_det=4, pairing="paired")))
    plane = Grid((3.8, 1.92, 0.0), (0.02, 0.02, 0.02), (21, 5, 1))  # a partial 8-cell block
    volume = Grid((3.85, 1.94, -0.04), (0.02, 0.04, 0.04), (16, 4, 3))  # whole blocks only
    wide = Grid((2.0, 0.3, 0.0), (0.25, 0.25, 0.25), (19, 15, 1))  # paths past both record ends
    small = dict(n_bins=200)
    # tiles: partial 8-cell rows, tiles past every grid edge, several detector tiles
    tiles = _with_blocks(_point_target_inputs(volume, **small), [[-1, -1, -1], [10, 2, 1]],
                         (9, 3, 2))
    many = _point_target_inputs(plane, n_det=DET_TILE + 4, **small)
    return (_both_modes("plane 21x5", _point_target_inputs(plane, **small))
            + _both_modes("volume 16x4x3", _point_target_inputs(volume, **small))
            + _both_modes("wide 19x15 past the record", _point_target_inputs(wide, **small))
            + _both_modes("plane in 2-row slabs", _point_target_inputs(plane, **small),
                          max_alloc_bytes=2 * 4 * 21)
            + _both_modes("volume in 2-plane slabs", _point_target_inputs(volume, **small),
                          max_alloc_bytes=2 * 4 * 16 * 4)
            + _both_modes(f"{DET_TILE + 4} detectors: two detector tiles", many)
            + _both_modes("tiles of 9x3x2 cells past the grid's edges", tiles, masked=True)
            + _both_modes("tiles, two detector tiles", _with_blocks(
                many, [[3, 1, 0], [16, 3, 0]], (8, 3, 1)), masked=True)
            + _both_modes("paired, two detector tiles", _point_target_inputs(
                plane, n_det=DET_TILE + 4, pairing="paired", **small))
            + _both_modes("confocal tiles", _with_blocks(_point_target_inputs(
                volume, pairing="confocal", **small), [[-1, -1, -1], [10, 2, 1]], (9, 3, 2)),
                masked=True))


OP = Operation(
    "ellipse_score", "ellipse_score", opencl, numpy, examples,
    tolerance_note="1e-3 of the peak (product) on smooth signals: a ~10 m path's fractional bin "
    "is off by ~0.003 bin in float32, times the slope per bin (< 0.05 of the peak): 1.5e-4 per "
    "detector. Log mode 3e-3 absolute where every detector is above 1e-4 of its peak. Tiles "
    "(blocks): the same, and cells outside the grid -inf on both sides.",
    bound="gathers (two 8-lane gathers of scalar loads per cell and detector)")
