"""How the hidden target reflects: the seam the forward model is specialised on.

A reflectance model splits the target's BRDF f(n, to_laser, to_detector) into a constant
`scale` (1/sr, applied on the host in float64 with the other physical constants) and a
dimensionless, direction-dependent `factor` that the forward kernel evaluates per (facet,
detector). The kernel gets the factor as the macro REFLECTANCE_FACTOR(n, to_laser, to_detector)
through `kernel_defines()`; `factor()` is its float64 twin. Lambertian reflection (the paper's)
has factor 1. A glossy model adds its own macro and twin here and nowhere else.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import require


@dataclass(frozen=True)
class Lambertian:
    """A diffuse reflector: f = brdf (1/sr) in every direction (paper: clothes 0.1284)."""

    brdf: float = 0.1284

    def __post_init__(self):
        require(isinstance(self.brdf, (int, float)) and math.isfinite(self.brdf)
                and self.brdf > 0, "target.brdf", f"must be a positive number, got {self.brdf!r}",
                "pass e.g. 0.1284 (the paper's clothes; 1/pi is a perfect white reflector)")

    @property
    def scale(self) -> float:
        return float(self.brdf)

    def kernel_defines(self) -> dict:
        return {}  # forward.cl's default REFLECTANCE_FACTOR is 1

    def factor(self, normals, to_laser, to_detector) -> np.ndarray:
        """(D, F) direction-dependent part: 1 for a Lambertian surface."""
        return np.ones(to_detector.shape[:-1])


def as_reflectance(value):
    """A number means a Lambertian BRDF of that value; a model passes through."""
    if isinstance(value, (int, float, np.floating)) and not isinstance(value, bool):
        return Lambertian(float(value))
    require(hasattr(value, "kernel_defines") and hasattr(value, "factor")
            and hasattr(value, "scale"), "target.brdf",
            f"expected a number or a reflectance model, got {type(value).__name__}",
            "pass e.g. 0.1284 or nlos_cl.Lambertian(0.1284)")
    return value
