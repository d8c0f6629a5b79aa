"""Search grids: regular lattices of candidate positions, in our internal frame (metres)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import require


@dataclass(frozen=True)
class Grid:
    """A regular grid of candidate positions: cell centres origin + index * step, per axis.

    The default is the paper's search plane z = 0 with x in [0, 6] m and y in (0, 6] m, 1 cm step.
    """

    origin: tuple = (0.0, 0.01, 0.0)
    step: tuple = (0.01, 0.01, 0.01)
    shape: tuple = (601, 600, 1)  # (nx, ny, nz)

    def __post_init__(self):
        origin = tuple(float(v) for v in np.asarray(self.origin, dtype=np.float64).reshape(-1))
        step = tuple(float(v) for v in np.asarray(self.step, dtype=np.float64).reshape(-1))
        shape = tuple(int(v) for v in np.asarray(self.shape).reshape(-1))
        require(len(origin) == 3 and all(map(math.isfinite, origin)), "grid.origin",
                f"expected three finite coordinates, got {self.origin!r}", "pass (x0, y0, z0)")
        require(len(shape) == 3 and all(n >= 1 for n in shape), "grid.shape",
                f"needs at least one cell along each axis, got {self.shape!r}",
                "pass (nx, ny, nz) with every count >= 1 (nz = 1 for a plane)")
        require(len(step) == 3 and all(math.isfinite(s) and s > 0 for s in step), "grid.step",
                f"must be three positive cell sizes, got {self.step!r}",
                "pass positive steps in metres, e.g. (0.01, 0.01, 0.01)")
        require(origin[1] > 0, "grid.origin",
                f"the grid starts at y = {origin[1]} m, on or behind the wall",
                "search only the hidden area y > 0")
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "step", step)
        object.__setattr__(self, "shape", shape)

    @classmethod
    def from_ranges(cls, x=(0.0, 6.0), y=(0.01, 6.0), z=(0.0, 0.0), step_m: float = 0.01) -> "Grid":
        """Inclusive ranges per axis, all on one step. Inverted or empty ranges are errors."""
        origin, shape = [], []
        for name, (lo, hi) in zip("xyz", (x, y, z)):
            require(math.isfinite(lo) and math.isfinite(hi) and hi >= lo, f"grid.{name}",
                    f"range ({lo}, {hi}) is empty or inverted", "pass (low, high) with high >= low")
            origin.append(lo)
            shape.append(int(math.floor((hi - lo) / step_m + 1e-6)) + 1)
        return cls(tuple(origin), (step_m,) * 3, tuple(shape))

    @property
    def n_cells(self) -> int:
        return self.shape[0] * self.shape[1] * self.shape[2]

    def axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return tuple(o + s * np.arange(n) for o, s, n in zip(self.origin, self.step, self.shape))

    def cell_centres(self) -> np.ndarray:
        """(nz, ny, nx, 3) positions, matching the score map's memory layout."""
        x, y, z = self.axes()
        zz, yy, xx = np.meshgrid(z, y, x, indexing="ij")
        return np.stack([xx, yy, zz], axis=-1)
