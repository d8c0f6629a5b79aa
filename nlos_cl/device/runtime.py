"""The host module: one OpenCL device with its context, queue, program cache, memory pool,
chunking and out-of-memory retry. It knows no operation: operations live in nlos_cl/ops, and
ops.backend.OpenCLBackend (a Runtime) runs them by name. Handles are pyopencl arrays that stay on
the device between stages; programs are built once per (source file, build options); buffers
come from a memory pool, so a stream of frames reuses device memory instead of allocating anew.
"""
from __future__ import annotations

import os
import random
import re
import sys
import tempfile
import threading
import warnings
from importlib import resources
from pathlib import Path

import numpy as np

from . import devices  # sets the PoCL cache folder before pyopencl loads
from . import programs
from ..core.tuning import CONSTANT_CACHE
from ..core.errors import DeviceError, warn

cl = devices.cl
import pyopencl.array as cla  # noqa: E402
import pyopencl.clrandom as clrandom  # noqa: E402
import pyopencl.tools as cltools  # noqa: E402



def _kernel_file(name: str) -> str:
    try:
        return resources.files("nlos_cl.kernels").joinpath(name).read_text()
    except (ModuleNotFoundError, FileNotFoundError):
        return (Path(__file__).resolve().parents[2] / "kernels" / name).read_text()


def kernel_source(name: str) -> str:
    """Text of kernels/<name>.cl with each `#include "x.h"` replaced by kernels/x.h, from the
    installed package or, failing that, the checkout (no -I path: works on every platform)."""
    return re.sub(r'^#include "([\w.]+\.h)"$', lambda m: _kernel_file(m.group(1)),
                  _kernel_file(f"{name}.cl"), flags=re.M)


def verbose() -> bool:
    """NLOS_CL_VERBOSE=1 (the CLI's --verbose sets it): show what the OpenCL compiler said."""
    return os.environ.get("NLOS_CL_VERBOSE", "").strip().lower() not in ("", "0", "false", "no")


class _Captured:
    """What C code wrote to file descriptor 2 inside the `with`: PoCL's clang prints its
    summary ('13 warnings generated.') there directly, below Python's sys.stderr and below
    pyopencl's CompilerWarning, so only a descriptor-level redirect keeps it off the terminal.
    The redirect is process-wide, hence the lock (two threads building at once); if descriptor 2
    cannot be redirected (closed, no temporary file) nothing is captured and nothing fails.
    When verbose() nothing is redirected: the compiler then writes straight to the terminal, so
    even an abort inside LLVM (whose message a redirect would swallow) is seen."""
    _lock = threading.Lock()

    def __enter__(self):
        self.text, self._saved, self._file = "", None, None
        self._lock.acquire()
        if verbose():
            return self
        try:
            sys.stderr.flush()
            self._file = tempfile.TemporaryFile()
            self._saved = os.dup(2)
            os.dup2(self._file.fileno(), 2)
        except (OSError, ValueError):
            self._restore()
        return self

    def _restore(self):
        if self._saved is not None:
            os.dup2(self._saved, 2)
            os.close(self._saved)
            self._saved = None

    def __exit__(self, *exc):
        try:
            self._restore()
            if self._file is not None:
                self._file.seek(0)
                self.text = self._file.read().decode("utf-8", "replace").strip()
                self._file.close()
        finally:
            self._lock.release()
        return False


def build_program(program, options, device, where: str):
    """Build `program`, keeping the compiler's output off the terminal: it is shown (on stderr)
    only when verbose() and, when the build fails, inside the DeviceError it raises. pyopencl's
    CompilerWarning (the same log, or 'Non-empty compiler output') is silenced for the same
    reason; the library's own warnings are untouched."""
    failure = None
    with _Captured() as said, warnings.catch_warnings():
        warnings.simplefilter("ignore", cl.CompilerWarning)
        try:
            program.build(options=options)
        except cl.RuntimeError as exc:
            failure = exc
    if failure is not None:
        raise DeviceError(f"{where} failed to build with {list(options)}:\n{failure}"
                          + (f"\n{said.text}" if said.text else "")) from failure
    log = (program.get_build_info(device, cl.program_build_info.LOG) or "").strip()
    output = "\n".join(t for t in (log, said.text) if t)
    if output and verbose():
        print(f"nlos_cl: OpenCL compiler output for {where} {list(options)}:\n{output}",
              file=sys.stderr, flush=True)
    return output


def float4(point) -> np.ndarray:
    """A point as an OpenCL float4 kernel argument (w = 0). Built as a structured scalar:
    pyopencl's make_float4 costs ~10x more, which a per-frame search launch notices."""
    p = np.asarray(point, dtype=np.float64).reshape(3)
    return np.array((float(p[0]), float(p[1]), float(p[2]), 0.0), dtype=cl.cltypes.float4)


def int4(v) -> np.ndarray:
    """Three integers as an OpenCL int4 kernel argument (w = 0)."""
    return np.array((int(v[0]), int(v[1]), int(v[2]), 0), dtype=cl.cltypes.int4)


def float4_rows(points) -> np.ndarray:
    """(n, 3) points as (n, 4) float32 rows for a float4 buffer (w = 0)."""
    pts = np.asarray(points, dtype=np.float32).reshape(-1, 3)
    out = np.zeros((len(pts), 4), dtype=np.float32)
    out[:, :3] = pts
    return out


class Runtime:
    """One OpenCL device with everything built for it. Use `get_runtime()` for a shared one."""

    def __init__(self, device=None, max_alloc_bytes: int | None = None):
        """max_alloc_bytes caps the intermediate buffers that grow with a product of sizes
        (facets x detectors, rows x filter window, grid cells); the device's own
        CL_DEVICE_MAX_MEM_ALLOC_SIZE by default. Work over the cap runs in chunks, each output
        value computed exactly as in one piece."""
        self.device = devices.choose_device(device)
        self.max_alloc_bytes = int(max_alloc_bytes or self.device.max_mem_alloc_size)
        self.context = cl.Context([self.device])
        self.queue = cl.CommandQueue(self.context)
        self.allocator = cltools.MemoryPool(cltools.ImmediateAllocator(self.queue))
        self._programs, self._kernels, self._constants, self._resources = {}, {}, {}, {}
        self.launched: set = set()  # (kernel file, kernel name) run so far (the oclgrind check)
        self.name = devices.describe(self.device)
        # a CPU device (PoCL, Intel's, Oclgrind): the ops pick their CPU paths from it
        self.on_cpu = bool(self.device.type & cl.device_type.CPU)

    # ------------------------------------------------------------ programs
    def kernel(self, source: str, name: str, **defines) -> "cl.Kernel":
        """Kernel `name` of kernels/<source>.cl built with -D defines; built and fetched once."""
        options = tuple(f"-D{k}={v}" for k, v in sorted(defines.items()))
        key = (source, options, name)
        kern = self._kernels.get(key)
        if kern is None:
            program = self._programs.get((source, options))
            if program is None:
                program = self._program(kernel_source(source), options,
                                        f"kernels/{source}.cl on {self.name}")
                self._programs[(source, options)] = program
            kern = self._kernels[key] = getattr(program, name)
            kern.nlos_source = (source, name)
        return kern

    def _program(self, text: str, options: tuple, where: str) -> "cl.Program":
        """Built from the binary stored by an earlier process where there is one (programs.py:
        no compiler runs, so there is no compiler output to show), else from source, and kept."""
        program = programs.load(self.context, self.device, text, options)
        if program is None:
            program = cl.Program(self.context, text)
            build_program(program, list(options), self.device, where)
            programs.store(program, self.device, text, options)
        return program

    def run(self, kernel, global_size, *args, local_size=None):
        """Enqueue; the local size is left to the runtime (best on CPU devices) unless given."""
        self.launched.add(getattr(kernel, "nlos_source", ("", kernel.function_name)))
        kernel.set_args(*[a.data if isinstance(a, cla.Array) else a for a in args])
        return cl.enqueue_nd_range_kernel(self.queue, kernel, global_size, local_size)

    def resource(self, key, factory):
        """Something built once per context (e.g. a random generator), by `factory()`."""
        if key not in self._resources:
            self._resources[key] = factory()
        return self._resources[key]

    # ------------------------------------------------------------ memory
    def empty(self, shape, dtype=np.float32):
        return cla.empty(self.queue, shape, dtype, allocator=self.allocator)

    def from_numpy(self, array):
        return cla.to_device(self.queue, np.ascontiguousarray(array, dtype=np.float32),
                             allocator=self.allocator)

    def finish(self):
        """Wait for everything queued (for timing a stage)."""
        self.queue.finish()

    def constant(self, array, dtype=np.float32):
        """A small read-only input (taps, spots, axes) on the device, uploaded once per content:
        a stream of frames with the same geometry re-uses it instead of copying each frame."""
        host = np.ascontiguousarray(array, dtype=dtype)
        key = (host.shape, host.dtype.str, host.tobytes())
        buf = self._constants.pop(key, None)
        if buf is None:
            buf = cla.to_device(self.queue, host)
        self._constants[key] = buf  # most recently used last
        while len(self._constants) > CONSTANT_CACHE:
            self._constants.pop(next(iter(self._constants)))
        return buf

    # ------------------------------------------------------------ chunking
    def groups(self, n: int, bytes_each: int, what: str) -> list[tuple[int, int]]:
        """Split n rows into consecutive groups whose buffer (bytes_each per row) fits under
        max_alloc_bytes."""
        per = self.max_alloc_bytes // max(int(bytes_each), 1)
        if per < 1:
            raise DeviceError(f"{what}: one row needs {bytes_each} bytes, more than this device "
                              f"allows in one buffer ({self.max_alloc_bytes} bytes). Fix: use "
                              "fewer bins, facets or grid cells per row")
        return [(i, min(i + per, n)) for i in range(0, n, per)]

    def shrinking_on_oom(self, stage):
        """Run stage(); if the device runs out of memory, free the pool, halve the chunk cap and
        retry, down to 1 MiB, then say what to reduce."""
        while True:
            try:
                return stage()
            except (cl.MemoryError, cl.RuntimeError) as exc:
                if "OUT_OF" not in str(exc) and "ALLOCATION" not in str(exc):
                    raise
                self.allocator.free_held()
                if self.max_alloc_bytes <= 1 << 20:
                    raise DeviceError(f"{self.name} ran out of memory even in 1 MiB chunks "
                                      f"({exc}). Fix: reduce the grid, the number of bins or "
                                      "detectors, or the facet count") from exc
                self.max_alloc_bytes //= 2
                warn(f"device out of memory: retrying in chunks of at most "
                     f"{self.max_alloc_bytes} bytes", RuntimeWarning)

    # ------------------------------------------------------------ the Backend protocol
    def standard_normal(self, shape, seed):
        """Seeded N(0, 1) draws from Philox (counter-based: the same stream on every device).

        One generator per context (its programs build once); for each call it is re-keyed from
        the seed exactly as pyopencl keys a fresh PhiloxGenerator(seed=seed), so a seed always
        means the same noise, frame after frame.
        """
        gen = self.resource("philox", lambda: clrandom.PhiloxGenerator(self.context, seed=0))
        draw = random.Random(seed)
        lo, hi = int(np.iinfo(np.int32).min), int(np.iinfo(np.int32).max)
        gen.key = [draw.randrange(lo, hi + 1) for _ in range(gen.key_length - 1)]
        gen.counter = [draw.randrange(lo, hi + 1) for _ in range(4)]
        if "philox built" in self._resources:
            return gen.normal(self.queue, shape, np.float32, allocator=self.allocator)
        # the first draw builds pyopencl's own Random123 program: its compiler output too is
        # kept off the terminal unless verbose
        with _Captured() as said, warnings.catch_warnings():
            warnings.simplefilter("ignore", cl.CompilerWarning)
            draws = gen.normal(self.queue, shape, np.float32, allocator=self.allocator)
        self._resources["philox built"] = True
        if said.text and verbose():
            print(f"nlos_cl: OpenCL compiler output for pyopencl's Philox generator:\n"
                  f"{said.text}", file=sys.stderr, flush=True)
        return draws

    def read_rows(self, score, iz, iy0, iy1):
        if not hasattr(score, "rows"):
            return score[iz, iy0:iy1].get(self.queue).astype(np.float64)
        return score.rows(self.queue, iz, iy0, iy1)

    def to_numpy(self, handle):
        return self.read(handle).astype(np.float64)

    def read(self, handle, out=None):
        """As stored (float32 from the device; a host array itself): for reading only; into
        `out` (a pyopencl Array's shape and dtype, reused: no new pages) where given."""
        return _read(handle, self.queue, out)


    def view(self, handle):
        """A read-only host view of a pyopencl Array on a CPU device, mapped (PoCL maps a
        buffer in place: no copy and no new pages; a 1,024 x 60,042-bin SPAD record's read into
        fresh pages took 0.2-0.6 s here, its map 0.1 ms); None elsewhere (a GPU's map is a copy:
        use `read`). The view shows the buffer as it is: valid until a kernel writes it (the
        next frame's filter), as a kept read is (localization.locator.detected_in)."""
        if not self.on_cpu or not hasattr(handle, "data") or handle.size == 0:
            return None
        rows, _ = cl.enqueue_map_buffer(self.queue, handle.data, cl.map_flags.READ,
                                        handle.offset, handle.shape, handle.dtype)
        rows.flags.writeable = False
        return rows


def _read(handle, queue, out=None):
    """Runtime.read: a host array itself, else the handle's values (into `out` if given:
    pyopencl Arrays take it, the score maps' own get does not)."""
    if isinstance(handle, np.ndarray):
        return handle
    return handle.get(queue) if out is None else handle.get(queue, ary=out)
