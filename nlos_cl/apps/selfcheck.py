"""`nlos-cl info`: the OpenCL devices found, the one chosen, and every registered operation
checked against its NumPy twin on that device (the examples and tolerances of nlos_cl/ops)."""
from __future__ import annotations

import sys


def self_check(runtime) -> list[tuple[str, float, float]]:
    """(operation: example, error, tolerance) for every operation's "check" examples."""
    from ..ops import OPERATIONS
    from ..ops.backend import NumpyBackend
    from ..ops.base import example_error
    from ..ops.opencl_backend import OpenCLBackend

    twin, results = NumpyBackend(), []
    for op in OPERATIONS.values():
        for example in op.examples("check"):
            device = runtime
            if example.max_alloc_bytes:
                device = OpenCLBackend(runtime.device, max_alloc_bytes=example.max_alloc_bytes)
            error = example_error(op, example, device, twin)
            results.append((f"{op.name}: {example.label}", error, example.tolerance))
    return results


def run(device=None) -> int:
    from ..device import devices
    entries = devices.list_devices()
    print("OpenCL platforms and devices:")
    if not entries:
        print("  none")
        print(devices.INSTALL_HELP)
        return 1
    for e in entries:
        print("  " + e.label)
    from ..ops.opencl_backend import get_runtime
    runtime = get_runtime(device)
    print(f"chosen: {runtime.name}")
    failed = False
    for name, err, tol in self_check(runtime):
        ok = err <= tol
        failed |= not ok
        print(f"  self-check {name:<48} error {err:.2e} (tolerance {tol:.0e}) "
              f"{'ok' if ok else 'FAILED'}")
    if failed:
        print("SELF-CHECK FAILED: the kernels disagree with the NumPy reference on this device",
              file=sys.stderr)
        return 2
    return 0


def main(args) -> int:
    return run(args.device)
