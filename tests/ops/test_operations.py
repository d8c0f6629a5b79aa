"""Every registered operation against its float64 NumPy twin, on every OpenCL device, with the
examples and tolerances its own module states (nlos_cl/ops/<op>.py: `examples("check")` and
`examples("tiny")`, the latter reaching partial blocks, chunked groups and slabs)."""
import pytest

from nlos_cl.ops.backend import NumpyBackend
from nlos_cl.ops import OPERATIONS
from nlos_cl.ops.base import example_error
from nlos_cl.ops.opencl_backend import OpenCLBackend as Runtime

CASES = [(op.name, size, i) for op in OPERATIONS.values() for size in ("tiny", "check")
         for i in range(len(op.examples(size)))]


def _id(case):
    name, size, i = case
    return f"{name}-{size}-{OPERATIONS[name].examples(size)[i].label}"


@pytest.mark.parametrize("case", CASES, ids=[_id(c) for c in CASES])
def test_operation_matches_twin(case, device_runtime):
    name, size, i = case
    op = OPERATIONS[name]
    example = op.examples(size)[i]
    runtime = device_runtime
    if example.max_alloc_bytes:  # a capped runtime on the same device: the chunked path
        runtime = Runtime(device_runtime.device, max_alloc_bytes=example.max_alloc_bytes)
    error = example_error(op, example, runtime, NumpyBackend())
    assert error <= example.tolerance, f"{op.name} {example.label}: {error:.3g} ({op.tolerance_note})"


def test_every_kernel_file_is_an_operation():
    from pathlib import Path
    kernels = {p.stem for p in (Path(__file__).resolve().parents[2] / "kernels").glob("*.cl")}
    assert kernels - {op.kernel_file for op in OPERATIONS.values()} == {"probes"}
