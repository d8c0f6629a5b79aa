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


def versions(runtime=None) -> list[tuple[str, str]]:
    """What a bug report needs: nlos_cl, Python, NumPy, PyOpenCL, and the OpenCL platform
    (PoCL or the vendor's driver), driver and device of `runtime`."""
    import platform

    import numpy

    import nlos_cl
    out = [("nlos_cl", nlos_cl.__version__), ("python", platform.python_version()),
           ("numpy", numpy.__version__)]
    try:
        import pyopencl
        out.append(("pyopencl", pyopencl.VERSION_TEXT))
    except ImportError:
        out.append(("pyopencl", "not installed"))
    if runtime is not None:
        dev = runtime.device
        out += [("platform", f"{dev.platform.name} {dev.platform.version}"),
                ("driver", dev.driver_version), ("device", dev.name.strip())]
    out.append(("os", platform.platform()))
    return out


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
    checks = self_check(runtime)
    failed = 0
    for name, err, tol in checks:
        ok = err <= tol
        failed += not ok
        print(f"  self-check {name:<48} error {err:.2e} (tolerance {tol:.0e}) "
              f"{'ok' if ok else 'FAILED'}")
    print("versions (for a bug report):")
    for name, value in versions(runtime):
        print(f"  {name:<9} {value}")
    if failed:
        print("SELF-CHECK FAILED: the kernels disagree with the NumPy reference on this device",
              file=sys.stderr)
        print(f"summary: {failed} of {len(checks)} self-checks FAILED on {runtime.device.name.strip()}")
        return 2
    print(f"summary: all {len(checks)} self-checks passed on {runtime.device.name.strip()}")
    return 0


def main(args) -> int:
    return run(args.device)
