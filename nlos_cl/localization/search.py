"""Coarse-to-fine scoring: the same argmax cell as scoring every cell, for a fraction of the work.

The fine grid is cut into blocks of f x f (x f) cells, f odd, so each block's centre is a fine
cell. Per frame:

1. score the block centres on *dilated* rows (nlos_cl/ops/max_filter.py): a cell of the
   block lies within R = (f - 1) / 2 |step| of its centre, and a cell's hidden path
   |c - O| + |c - spot| moves by at most 2 per metre the cell moves, so every fine cell's path
   lies within 2 R of the centre's, and the dilated rows (a running maximum over 2 R of path,
   plus a bin for float32 rounding, over the record widened by as much, since the maximum
   reaches past its ends) bound every fine cell of the block from above: U(block) (where
   that window spans more bins than max_filter's one-launch form, maxima of blocks of bins
   dilated over blocks: `_bounding_rows`, a slightly looser bound from one read of the
   record instead of max_filter's three reads and three writes per bin);
2. score the TOP_CENTRES block centres with the highest U exactly (fine cells): the best of
   them, L, is a real fine cell's score (`run`; `fused` scores every centre);
3. score every fine cell of the blocks with U >= L (a relative slack of 1e-4 for float32
   rounding): any cell scoring more than L lies in one of them, so their best cell is the
   grid's argmax. Ties go to the lowest flat index, as exhaustive scoring's argmax does.

Nothing here is a guess: the margin is the exact path bound. The signal's width W (filter and
pulse in path metres) only sets the speed: f is the largest odd factor with
(f - 1) |step| <= W, so a block's path spread 2 R stays within one signal width and U is tight
(few candidate blocks). The cells are scored by the same kernel code as a whole grid (the
`blocks` form of ellipse_score), so the scores, the argmax and the estimator's neighbourhood are
bit-identical to exhaustive scoring. Where the bound rules little out (a flat map), the whole
grid is scored instead.

`fused` runs steps 1-3 on the device (nlos_cl/ops/fused_search.py): the row stats and the
dilation (one launch: stats_dilate), one launch
scoring the coarse cells on both kinds of rows, one launch that selects, refines, takes the
argmax and scores the best cell's 3 x 3 x 3 neighbours, and ONE read of 35 floats per frame.
`run` (the host picks the blocks: two reads of the coarse maps, one of the fine scores) stays
for more detectors than one scoring pass takes and for coarse grids too large for one work
group.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.grid import Grid
from ..ops.argmax_patch import decode
from ..ops.ellipse_score import DET_TILE
from ..ops.fused_search import MAX_COARSE, centre_inside, coarse_grid
from ..ops.max_filter import DIRECT_MAX_WINDOW

SEARCHES = ("exhaustive", "coarse_to_fine", "auto")  # auto: nlos_cl/plans.py (Locator)
MIN_CELLS = 4096  # smaller grids are scored exhaustively
SLACK = 1e-4  # relative: float32 rounding between a bound and a fine score
MAX_SHARE = 0.5  # refine at most this share of the grid, else score it all
# Block centres scored exactly for the threshold L (`run`): those with the highest bounds. Every
# centre's exact score was one more pass over the coarse grid for every detector: on a
# 1,024-spot SPAD patch (14,520 centres) 0.13 s of a 0.20 s search; L only has to be a real
# cell's score, and the best centres' bounds are the highest (the same candidates there).
TOP_CENTRES = 64


def coarse_factor(grid: Grid, width_m: float) -> int:
    """The largest odd f with (f - 1) |step| <= width_m (|step| over the axes with > 1 cell)."""
    diag = math.sqrt(sum(s * s for s, n in zip(grid.step, grid.shape) if n > 1))
    if grid.n_cells < MIN_CELLS or diag == 0.0:
        return 1
    f = 1 + int(math.floor(width_m / diag + 1e-9))
    return max(1, f if f % 2 else f - 1)


# Where the dilation's window (2 half + 1 bins) is longer than max_filter's one-launch form
# takes, the bound dilates maxima of blocks of B = half // BLOCKS_PER_HALF bins instead (a
# 1,024-spot SPAD patch of 1 ps bins, half 661: max_filter's two passes 0.46 s, the blocks
# ~0.05 s; the window grows by ~2 B, an eighth).
BLOCKS_PER_HALF = 16


def _bound_blocks(half: int) -> tuple[int | None, int | None]:
    """(B, h): bins per block and the dilation in blocks (h B >= half + 1 + B: any point
    between two samples has its whole window inside both samples' blocks), or (None, None)
    where max_filter dilates the bins in one launch."""
    if 2 * half + 1 <= DIRECT_MAX_WINDOW:
        return None, None
    block = max(1, half // BLOCKS_PER_HALF)
    return block, -(-(half + 1) // block) + 1


@dataclass
class Found:
    """The search's result: the best fine cell, its score, and what it cost."""

    index: tuple  # (ix, iy, iz)
    score: float
    blocks: int  # candidate blocks scored cell by cell (-1: the whole grid was scored)
    cells_scored: int


class CoarseToFine:
    """A search plan for one grid and one score axis (built once, run per frame)."""

    def __init__(self, grid: Grid, inv_dpath, width_m: float, factor: int | None = None):
        self.grid = grid
        self.factor = int(factor) if factor else coarse_factor(grid, width_m)
        f = self.factor
        # per-axis factor; never more than the axis has cells, so every block's centre cell
        # exists (a thin slab of a huge grid keeps its few planes)
        self.fa = tuple(min(f, n) if n > 1 else 1 for n in grid.shape)
        self.coarse = coarse_grid(grid, self.fa)
        self.valid = centre_inside(grid, self.fa)  # coarse cells whose centre is a fine cell
        radius = 0.5 * math.sqrt(sum(((fa - 1) * s) ** 2 for s, fa in zip(grid.step, self.fa)))
        self.half = int(math.ceil(2.0 * radius * float(np.max(inv_dpath)) + 0.01)) + 1
        self.block, self.block_half = _bound_blocks(self.half)
        self._bufs = {}

    @property
    def useful(self) -> bool:
        return self.factor > 1

    def fusable(self, n_detectors: int) -> bool:
        """Whether `fused` takes this search (one scoring pass, one work group's coarse grid)."""
        return self.useful and n_detectors <= DET_TILE and self.coarse.n_cells <= MAX_COARSE

    def fused(self, be, signal, geometry, out=None):
        """(Found, 3 x 3 x 3 scores around it (NaN outside the grid), the result handle), or
        (None, None, handle) when no block was a candidate; one read. geometry: (spots,
        laser, path0, inv_dpath, log_mode, log_floor). Row stats and dilation in one launch
        where the window is short (stats_dilate), else row_stats and max_filter."""
        if 2 * self.half + 1 <= DIRECT_MAX_WINDOW:
            stats, dilated = be.call("stats_dilate", signal, self.half,
                                     out=self._bufs.get("prepared"))
            self._bufs["prepared"] = (stats, dilated)
        else:
            stats = be.call("row_stats", signal, out=self._bufs.get("stats"))
            dilated = be.call("max_filter", signal, self.half, out=self._bufs.get("dilated"))
            self._bufs["stats"], self._bufs["dilated"] = stats, dilated
        result = be.call("fused_search", signal, dilated, stats, *geometry[:4], self.grid,
                         self.fa, self.half, *geometry[4:], out=out)
        index, score, count, patch = decode(be.to_numpy(result))
        if index is None:
            return None, None, result
        n = int(count)
        return Found(index, score, n, n * int(np.prod(self.fa))), patch, result

    def _score(self, be, key, signal, args, grid, *blocks):
        self._bufs[key] = be.call("ellipse_score", signal, *args[:5], grid, *args[5:],
                                  *blocks, out=self._bufs.get(key))
        return self._bufs[key]

    def candidates(self, be, signal, args):
        """(block first cells (n, 3), L): the blocks that may hold a cell scoring >= L, L the
        best exact score of the TOP_CENTRES centres with the highest bounds (steps 1-2)."""
        log_mode = args[5]
        dilated, wide = self._bounding_rows(be, signal, args)
        bound = be.to_numpy(self._score(be, "bound", dilated, wide, self.coarse))
        best = self._best_centre(be, signal, args, bound)
        thr = best - SLACK * (abs(best) + (1.0 if log_mode else 0.0))
        iz, iy, ix = np.nonzero(bound >= thr)
        return np.stack([ix, iy, iz], axis=1) * np.asarray(self.fa), best

    def _best_centre(self, be, signal, args, bound) -> float:
        """The best exact score among the (at most) TOP_CENTRES block centres inside the grid
        with the highest bounds, each scored as the fine cell it is."""
        flat = np.where(self.valid & ~np.isnan(bound), bound, -np.inf).reshape(-1)
        k = min(TOP_CENTRES, flat.size)
        top = np.argpartition(flat, flat.size - k)[flat.size - k:]
        top = top[self.valid.reshape(-1)[top]]
        iz, iy, ix = np.unravel_index(top, bound.shape)
        fa = np.asarray(self.fa)
        cells = np.stack([ix, iy, iz], axis=1) * fa + (fa - 1) // 2
        scores = be.to_numpy(self._score(be, "centres", signal, args, self.grid, cells,
                                         (1, 1, 1)))
        return float(scores.max())

    def _bounding_rows(self, be, signal, args):
        """(rows, args for them) that bound every fine cell of a coarse block from above:
        the record dilated by `half` bins (module docstring, step 2), or, where that window
        is long (`_bound_blocks`), the maxima of blocks of B bins dilated by h blocks and read
        on an axis B times coarser: sample m stands at bin (m - h) B, and between samples b
        and b + 1 both cover every bin within `half` of any point between them, so their
        interpolation bounds what the dilated record would (a window ~2 B wider, still exact
        for the search: only the bound is looser)."""
        if self.block is None:
            dilated = be.call("max_filter", signal, self.half, out=self._bufs.get("dilated"))
            self._bufs["dilated"] = dilated
            return dilated, args[:3] + (args[3] - self.half / args[4],) + args[4:]
        b, h = self.block, self.block_half
        blocks = be.call("block_max", signal, b, out=self._bufs.get("blocks"))
        dilated = be.call("max_filter", blocks, h, out=self._bufs.get("dilated"))
        self._bufs["blocks"], self._bufs["dilated"] = blocks, dilated
        return dilated, args[:3] + (args[3] - h * b / args[4], args[4] / b) + args[5:]

    def run(self, be, signal, args) -> Found | None:
        """args: (stats, spots, laser, path0, inv_dpath, log_mode, log_floor). None: the bound
        rules out too little; score the whole grid instead."""
        blocks, _ = self.candidates(be, signal, args)
        per_block = int(np.prod(self.fa))
        if not 0 < len(blocks) * per_block <= MAX_SHARE * self.grid.n_cells:
            return None
        scores = be.to_numpy(self._score(be, "fine", signal, args, self.grid, blocks,
                                         self.fa))
        idx = blocks[:, None, None, None, :] + np.stack(np.meshgrid(
            np.arange(self.fa[2]), np.arange(self.fa[1]), np.arange(self.fa[0]),
            indexing="ij")[::-1], axis=-1)
        nx, ny, _ = self.grid.shape
        flat = (idx[..., 2] * ny + idx[..., 1]) * nx + idx[..., 0]
        top = scores.max()
        tied = scores == top
        win = int(np.argmin(np.where(tied, flat, np.iinfo(np.int64).max)))
        cell = tuple(int(v) for v in idx.reshape(-1, 3)[win])
        return Found(cell, float(top), len(blocks), len(blocks) * per_block)

    def neighbourhood(self, be, signal, args, index):
        """The 3 x 3 x 3 cells around `index` (clipped to the grid) as (their Grid, their
        scores on the backend), bit-identical to the same cells of a whole-grid score map."""
        lo = [max(i - 1, 0) for i in index]
        hi = [min(i + 2, n) for i, n in zip(index, self.grid.shape)]
        tile = tuple(h - low for low, h in zip(lo, hi))
        sub = Grid(tuple(o + s * i for o, s, i in zip(self.grid.origin, self.grid.step, lo)),
                   self.grid.step, tile)
        scores = be.call("ellipse_score", signal, *args[:5], self.grid, *args[5:],
                         np.array([lo]), tile)
        return sub, scores.reshape(tile[2], tile[1], tile[0])
