"""The two backends every stage runs on: an OpenCL device (`OpenCLBackend` in
opencl_backend.py, a nlos_cl.device.runtime.Runtime that runs operations by name) or the float64
NumPy twins (`NumpyBackend`). Both satisfy `Backend`; operations are not methods of either but
entries of the registry (nlos_cl/ops), called by name: `backend.call("gauss_filter", x, taps)`
or, equivalently, `backend.gauss_filter(x, taps)`."""
from __future__ import annotations

from typing import Protocol

import numpy as np

from .registry import OperationCalls, operation


class Backend(Protocol):
    name: str

    def from_numpy(self, array): ...
    def to_numpy(self, handle) -> np.ndarray: ...  # a float64 copy
    def read(self, handle) -> np.ndarray: ...  # as stored (float32 from a device): read only
    def finish(self) -> None: ...
    def standard_normal(self, shape, seed: int): ...
    def read_rows(self, score, iz: int, iy0: int, iy1: int) -> np.ndarray: ...
    def call(self, op: str, *args, out=None): ...


class NumpyBackend(OperationCalls):
    """The reference backend: every operation's float64 NumPy twin, run synchronously."""

    name = "numpy-reference"

    def from_numpy(self, array):
        return np.array(array, dtype=np.float64)

    def to_numpy(self, handle):
        return np.array(handle, dtype=np.float64)

    def read(self, handle):
        """The values as they are (no copy): the caller only reads them."""
        return np.asarray(handle)

    def finish(self):
        """Nothing is queued: NumPy runs synchronously."""

    def standard_normal(self, shape, seed):
        return np.random.default_rng(seed).standard_normal(shape)

    def read_rows(self, score, iz, iy0, iy1):
        return np.array(score[iz, iy0:iy1], dtype=np.float64)

    def call(self, op, *args, out=None):
        return operation(op).numpy(*args)


def read_values(backend, handle) -> np.ndarray:
    """A handle's values on the host for reading, in the dtype they are stored in (a float64
    copy of a SPAD record, 1,024 x 60,000 bins, costs ~1 s; backends without `read`
    give to_numpy's copy)."""
    read = getattr(backend, "read", None)
    return backend.to_numpy(handle) if read is None else read(handle)


def resolve_backend(backend=None):
    """None: the shared OpenCL runtime on the default device; 'reference' or 'numpy': the
    float64 NumPy twins; a device spec string ('0:0', 'pocl', ...) or a backend object."""
    if backend is None or isinstance(backend, str):
        if isinstance(backend, str) and backend.lower() in ("reference", "numpy"):
            return NumpyBackend()
        from .opencl_backend import get_runtime  # pyopencl loads only for a device backend
        return get_runtime(backend)
    return backend
