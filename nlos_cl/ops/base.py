"""What an operation is: a kernel file, its OpenCL launcher, its float64 NumPy twin with the same
signature, and example inputs with the tolerance that justifies comparing the two. The tests,
`nlos-cl info`'s self-check, the benchmark and the oclgrind check all walk the registry
(nlos_cl/ops/__init__.py) and run these examples; none of them knows an operation by name."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..core.constants import TINY

SIZES = ("tiny", "check", "bench")  # oclgrind (every branch, tiny) | tests and self-check | bench


def relative_error(a, b) -> float:
    """max |a - b| / max |b|: the error of a float32 kernel against its float64 twin."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return float(np.abs(a - b).max() / max(np.abs(b).max(), TINY))


@dataclass(frozen=True)
class Example:
    """One set of inputs. `inputs(backend)` returns the positional arguments of the operation on
    that backend (device inputs made with backend.from_numpy); `error(device, twin)` compares
    the two results (both as host arrays, or tuples of them) and must stay <= `tolerance`."""

    label: str
    inputs: Callable
    tolerance: float
    error: Callable = relative_error
    max_alloc_bytes: int | None = None  # run on a Runtime capped like this (forces chunking)
    work: float = 0.0  # bench: units of work done, for the throughput column
    unit: str = ""  # bench: what `work` counts
    # bench: where the twin would take minutes, it is timed on these inputs instead and its
    # time divided by `twin_fraction` (the share of the work they hold)
    twin_inputs: Callable | None = None
    twin_fraction: float = 1.0


@dataclass(frozen=True)
class Operation:
    name: str
    kernel_file: str  # kernels/<kernel_file>.cl
    opencl: Callable  # (runtime, *args, out=None) -> result on the device
    numpy: Callable  # (*args) -> float64 result, the twin
    examples: Callable  # (size in SIZES) -> list[Example]
    tolerance_note: str  # why the examples' tolerances are what they are
    bound: str = ""  # bench: what limits the kernel (see docs/results/performance/performance.md)


def to_host(backend, result):
    """A result (device handle, array, or tuple of them) as float64 host arrays."""
    if isinstance(result, tuple):
        return tuple(to_host(backend, r) for r in result)
    if isinstance(result, (int, float)):
        return np.asarray(result, np.float64)
    return backend.to_numpy(result)


def run_example(op: Operation, example: Example, backend):
    return to_host(backend, backend.call(op.name, *example.inputs(backend)))


def example_error(op: Operation, example: Example, device, twin) -> float:
    """The example's error between a device backend and the twin backend."""
    return float(example.error(run_example(op, example, device), run_example(op, example, twin)))
