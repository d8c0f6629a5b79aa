"""The OpenCL backend: a Runtime (nlos_cl.device.runtime: context, queue, programs, memory,
chunking) that runs registered operations by name, retrying in smaller chunks when the device
runs out of memory; one per device spec, shared."""
from __future__ import annotations

from ..device.runtime import Runtime
from .registry import OperationCalls, operation


class OpenCLBackend(OperationCalls, Runtime):
    """A Runtime that runs registered operations by name: `call("gauss_filter", ...)`."""

    reads_into = True  # read(handle, out=...) fills a given host array (Runtime.read)

    def call(self, op, *args, out=None):
        """Run a registered operation's launcher; out of device memory, retry in smaller chunks."""
        launcher = operation(op).opencl
        return self.shrinking_on_oom(lambda: launcher(self, *args, out=out))


_shared: dict = {}


def get_runtime(device=None) -> OpenCLBackend:
    """A Runtime per device spec, created once and reused (programs stay built)."""
    key = device if device is None or isinstance(device, str) else id(device)
    runtime = _shared.get(key)
    if runtime is None:
        runtime = _shared[key] = OpenCLBackend(device)
    return runtime
