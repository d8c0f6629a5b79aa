"""The registry of device operations. Each is kernels/<op>.cl + nlos_cl/ops/<op>.py (its
definition, OpenCL launcher and float64 NumPy twin, with example inputs and tolerances) + one
line below. Backends call them by name (`backend.call("gauss_filter", ...)`, or
`backend.gauss_filter(...)`); tests, self-check, bench and the oclgrind check walk this list."""
from . import (add_awgn, argmax, ellipse_score, forward, gauss_filter, row_stats,
               subtract_background)
from . import max_filter  # noqa: E402  (coarse-to-fine scoring's bound)
from . import argmax_patch, fused_search, stats_dilate  # noqa: E402  (one read per frame)
from .base import Example, Operation

OPERATIONS: dict[str, Operation] = {op.name: op for op in (
    forward.OP,
    gauss_filter.OP,
    row_stats.OP,
    add_awgn.OP,
    ellipse_score.OP,
    argmax.OP,
    subtract_background.OP,
    max_filter.OP,
    argmax_patch.OP,
    fused_search.OP,
    stats_dilate.OP,
)}

__all__ = ["OPERATIONS", "Example", "Operation"]
