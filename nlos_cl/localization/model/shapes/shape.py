"""The Shape protocol: what the model fit needs of a target shape, and the shapes it knows.

A shape is a module (plate.py, box.py, ellipsoid.py, cylinder.py, capsule.py) whose rows of
parameters start x, y, z (the centre) and end with the yaw; the fit reads its names, bounds, steps and
scales, and asks it for the lit facets of a row, its extent and its normal. A closed shape
(CLOSED) has the box's parameters, is fitted from the plate's starts (policy.closed) and says
how rounder starts look (`rounder_sizes`). A new shape is one module with these members and
one entry in SHAPES (docs/architecture.md walks through it)."""
from __future__ import annotations

from typing import Protocol

import numpy as np

from . import box, capsule, cylinder, ellipsoid, plate

MEMBERS = ("NAMES", "N_PARAMS", "YAW", "LOWER", "UPPER", "STEPS", "X_SCALE", "CLOSED",
           "model_facets", "extent", "normal_of")


class Shape(Protocol):
    NAMES: tuple  # parameter names, x, y, z first
    N_PARAMS: int
    YAW: int  # the yaw's index
    LOWER: np.ndarray  # the fit's bounds, per parameter
    UPPER: np.ndarray
    STEPS: np.ndarray  # absolute finite-difference steps (float32 kernels: not relative)
    X_SCALE: np.ndarray  # typical scales (the LM fit's variable scaling)
    CLOSED: bool  # a closed shape (the box's parameters), or an open surface (the plate)

    def model_facets(self, p, lattice, spots, laser):
        """What the forward model sees of row p (the facets the laser spot and detectors can
        see): (facets, pulse blur m, per-detector path shift), or a list of such parts, one
        forward call each (their histograms add)."""

    def extent(self, p) -> np.ndarray:
        """Size along the shape's own axes (across, up, along the normal), m."""

    def normal_of(self, p) -> np.ndarray:
        """The unit normal of the face towards the wall."""


SHAPES: dict[str, Shape] = {"plate": plate, "box": box, "ellipsoid": ellipsoid,
                             "cylinder": cylinder, "capsule": capsule}
MODELS = {name: f"upright {name}" for name in SHAPES}  # how reports name them
# The closed families a target is tried as (policy.closed), in SHAPES' order.
CLOSED_SHAPES = tuple(s for s in SHAPES.values() if s.CLOSED)


def name_of(shape) -> str:
    """'plate', 'box', ... for a shape module."""
    return next(name for name, s in SHAPES.items() if s is shape)
