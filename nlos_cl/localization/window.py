"""The paper's argmax searched inside a window of the region: the cells of the Locator's grid
within a box (a tracker's gates around its predictions, nlos_cl.tracking.gated), not the whole
region. `Locator(..., within=(lo, hi))`.

The window is a box of the region's own cells, scored as one tile of the region's grid
(ellipse_score's blocks form: the region's origin and cell indices), so its scores are the
region's scores of those cells, bit for bit, and its best cell the region's wherever the
region's best cell lies in it. (A sub-grid with its own origin computes its cells' float32
coordinates otherwise: ~1 ulp apart, scores 1e-3 apart, enough to move a near-tie.)

A window is searched where it scores fewer cells than the region's own search (the one
search="auto" chose) did on its last frame: every cell, or coarse-to-fine's coarse cells twice
and its candidate blocks. Two crossing targets on an 8-spot circle (a 3-D region of ~4 M cells
that coarse-to-fine cannot prune): 44-59 -> 6-7 ms a frame; on the consumer sensor's walk the
gates are wide (the argmax scatters ~0.3 m) and coarse-to-fine over the region stays cheaper.
One rule keeps the windowed answer honest: where the window's best cell lies on one of its
faces inside the region, the region's maximum may lie beyond it, and the Locator searches the
whole region instead (`on_inner_face`)."""
from __future__ import annotations

import math

import numpy as np

from ..core.errors import require
from ..core.grid import Grid
from ..ops.argmax_patch import decode


def checked_box(within) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) as two finite (3,) arrays with lo <= hi, or a clear error naming `within`."""
    try:
        lo, hi = (np.asarray(v, dtype=np.float64).reshape(3) for v in within)
    except (TypeError, ValueError):
        lo = hi = None
    if lo is None or not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))
                          and np.all(lo <= hi)):  # (the message only then: a repr per frame
        # of a tracker's box cost 0.3 ms)
        require(False, "within", f"must be a box (lo, hi) of two finite (x, y, z) corners "
                f"with lo <= hi, got {within!r}", "pass e.g. ((1.5, 1.0, -0.5), (2.5, 2.0, "
                "0.5)) in metres, or None for the whole region")
    return lo, hi


def sub_grid(grid: Grid, lo, hi, max_cells: float) -> tuple[Grid, tuple] | None:
    """(the window's grid, its first cell's index in `grid`): the cells of `grid` whose centres
    lie in [lo, hi] (a plane's one cell along its normal), or None where that is no saving
    (more than `max_cells`: what the region's own search scores) or no cell at all."""
    first, shape = [], []
    for o, s, n, a, b in zip(grid.origin, grid.step, grid.shape, lo, hi):
        if n == 1:  # a plane's one cell: the window keeps it
            first.append(0)
            shape.append(1)
            continue
        i0 = max(int(math.ceil((a - o) / s - 1e-9)), 0)
        i1 = min(int(math.floor((b - o) / s + 1e-9)), n - 1)
        if i1 < i0:
            return None
        first.append(i0)
        shape.append(i1 - i0 + 1)
    if np.prod(shape, dtype=np.float64) >= max_cells:
        return None
    origin = tuple(o + s * i for o, s, i in zip(grid.origin, grid.step, first))
    return Grid(origin, grid.step, tuple(shape)), tuple(first)


def on_inner_face(index, first, window: Grid, grid: Grid) -> bool:
    """Does the window's cell `index` lie on a face of the window that is not a face of the
    region (where the region's best cell may lie beyond the window)?"""
    for i, f, n, full in zip(index, first, window.shape, grid.shape):
        if n == 1:
            continue
        if (i == 0 and f > 0) or (i == n - 1 and f + n < full):
            return True
    return False


class WindowSearch:
    """A Locator's windowed searches: `run` one, `searched` after each whole-grid search (whose
    cost a window must beat). last: the window the last frame's argmax came from, or None."""

    def __init__(self, grid: Grid):
        self.grid, self.full_cells, self.last = grid, grid.n_cells, None

    def searched(self, found, search) -> None:
        """The whole grid was searched: every cell (found None) or coarse to fine (`search`'s
        coarse cells, scored twice, and found's candidate blocks)."""
        self.full_cells = self.grid.n_cells if found is None else \
            2 * search.coarse.n_cells + found.cells_scored

    def run(self, be, handle, args, box, result):
        """(best cell's index in the grid, its score, its 3 x 3 x 3 patch, the result buffer)
        from the window `box`: its cells scored as one tile of the grid (ellipse_score's
        blocks form: the grid's own origin and indices, so the grid's scores bit for bit) and
        their argmax and patch on the device (argmax_patch, one read). None where the window
        is no saving or its best cell lies on its inner face. args: () -> the scoring's
        (stats, spots, laser, path0, inv_dpath, log_mode, log_floor)."""
        cut = sub_grid(self.grid, *box, self.full_cells)
        if cut is None:
            return None
        window, first = cut
        nx, ny, nz = window.shape
        a = args()
        scores = be.call("ellipse_score", handle, *a[:5], self.grid, *a[5:], np.array([first]),
                         window.shape)
        result = be.call("argmax_patch", scores.reshape(nz, ny, nx), out=result)
        index, best, _, patch = decode(be.to_numpy(result))
        if index is None or on_inner_face(index, first, window, self.grid):
            return None
        self.last = window
        return tuple(int(i + f) for i, f in zip(index, first)), best, patch, result
