"""The registry of device operations. Each is kernels/<op>.cl + nlos_cl/ops/<op>.py (its
definition, OpenCL launcher and float64 NumPy twin, with example inputs and tolerances) + one
line below. Backends call them by name (`backend.call("gauss_filter", ...)`, or
`backend.gauss_filter(...)`); tests, self-check, bench and the oclgrind check walk this list."""
from . import (add_awgn, argmax, argmax_patch, block_max, ellipse_score, forward, fused_search,
               gauss_filter, max_filter, plate_model, row_stats, stats_dilate, subtract_background)
from .base import Operation

OPERATIONS: dict[str, Operation] = {op.name: op for op in (
    forward.OP,
    gauss_filter.OP,
    row_stats.OP,
    add_awgn.OP,
    ellipse_score.OP,
    argmax.OP,
    subtract_background.OP,
    max_filter.OP,
    block_max.OP,
    argmax_patch.OP,
    fused_search.OP,
    stats_dilate.OP,
    plate_model.OP,
)}


def operation(name: str) -> Operation:
    try:
        return OPERATIONS[name]
    except KeyError:
        raise AttributeError(f"no operation {name!r}; registered: {sorted(OPERATIONS)}") from None


class OperationCalls:
    """`backend.<op>(...)` for every registered operation."""

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        op = operation(name)
        return lambda *args, **kw: self.call(op.name, *args, **kw)
