"""Small geometric types and validators shared by the scene, the meshes, the grid and the
model fits (no trimesh here: what only needs facets stays light)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import require


def as_point(value, field_name: str) -> np.ndarray:
    """A finite [x, y, z] as our own float64 copy (the caller's array is never aliased)."""
    arr = np.array(value, dtype=np.float64)
    require(arr.shape == (3,), field_name, f"expected a point [x, y, z], got shape {arr.shape}",
            "pass three coordinates in metres")
    require(bool(np.all(np.isfinite(arr))), field_name, f"non-finite coordinate {arr.tolist()}",
            "pass finite coordinates in metres")
    return arr


@dataclass(frozen=True)
class Facets:
    """A target cut into small flat pieces: centre, outward unit normal, area (m^2)."""

    centres: np.ndarray
    normals: np.ndarray
    areas: np.ndarray

    @property
    def count(self) -> int:
        return self.areas.shape[0]
