"""The paper's estimator (Section 3.2): the argmax of the joint likelihood, refined below the
cell size by a parabola per axis."""
from __future__ import annotations

import numpy as np

from ..core.constants import TINY
from ..core.grid import Grid
from ..ops.argmax_patch import neighbourhood
from .estimate import (
    Capabilities,
    Estimate,
    LocatedTarget,
    Prior,
    Scored,
    check_signal,
    parabolic_offsets,
)


class PaperArgmax:
    """The paper's estimator (Section 3.2): the cell of maximum joint likelihood, refined with
    a parabola per axis through the log-score of the best cell and its two neighbours."""

    name = "paper"
    # the best cell's neighbourhood is all it reads, and its answer is what the Locator's fused
    # search computes on the device: a frame costs one small read
    capabilities = Capabilities(local=True, is_paper=True, paired=True)

    def estimate(self, scored: Scored, prior: Prior | None = None):
        """The argmax of `scored` (a prior changes nothing: the paper's estimate has no start)."""
        be, grid = scored.backend, scored.grid
        flat, best = be.call("argmax", scored.scores)
        check_signal(flat >= 0, best, scored.log_mode, scored.n_detectors)
        nx, ny, _ = grid.shape
        iz, rem = divmod(flat, nx * ny)
        iy, ix = divmod(rem, nx)
        patch = neighbourhood(lambda z, a, b: be.read_rows(scored.scores, z, a, b), grid.shape,
                              (ix, iy, iz))
        return self.from_patch((ix, iy, iz), best, patch, grid, scored.log_mode,
                               scored.n_detectors)

    def from_patch(self, index, best, patch, grid: Grid, log_mode: bool, n_detectors: int):
        """The estimate from the best cell's index (ix, iy, iz) on `grid` (None: no cell), its
        score and the 3 x 3 x 3 scores around it (NaN outside the grid), as the device's fused
        searches return them (nlos_cl/ops/fused_search.py, argmax_patch.py): no launch."""
        check_signal(index is not None, best, log_mode, n_detectors)
        cell = np.array([o + s * i for o, s, i in zip(grid.origin, grid.step, index)])
        logp = patch if log_mode else np.log(np.maximum(patch, TINY))
        position = cell + parabolic_offsets(logp) * np.asarray(grid.step)
        return Estimate([LocatedTarget(position)], cell, best)
