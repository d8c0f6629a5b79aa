"""The host module: owns the OpenCL context, queue, compiled programs, kernels and buffers.

`Runtime` has the same stage methods, with the same signatures, as `reference.NumpyBackend`;
handles are pyopencl arrays that stay on the device between stages. Programs are built once per
(source file, build options) and kernels fetched once; buffers come from a memory pool, so a
stream of frames reuses device memory instead of allocating anew.
"""
from __future__ import annotations

import math
import random
import warnings
from importlib import resources
from pathlib import Path

import numpy as np

from . import devices  # sets the PoCL cache folder before pyopencl loads
from .errors import DeviceError
from .histograms import Grid
from .reference import REACH_SIGMAS
from .scene import Facets

cl = devices.cl
import pyopencl.array as cla  # noqa: E402
import pyopencl.clrandom as clrandom  # noqa: E402
import pyopencl.tools as cltools  # noqa: E402

FACET_CHUNK = 64  # facets per culling chunk in the forward kernel
FORWARD_BLOCK = 15  # bins per work item in pulse_bins (BLOCK in forward.cl)
FILTER_BLOCK = 32  # outputs per work item in gauss_filter (two float16 accumulators)
ARGMAX_ITEMS = 1024  # work items in the first argmax stage


def kernel_source(name: str) -> str:
    """Text of kernels/<name>.cl, from the installed package or, failing that, the checkout."""
    try:
        return resources.files("nlos_cl.kernels").joinpath(f"{name}.cl").read_text()
    except (ModuleNotFoundError, FileNotFoundError):
        return (Path(__file__).resolve().parent.parent / "kernels" / f"{name}.cl").read_text()


def _build_quietly(program, options, device):
    """Build; pass on compiler messages except PoCL's note that float16 arguments change the
    ABI without AVX-512 (harmless: nothing in a kernel crosses an ABI boundary)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", cl.CompilerWarning)
        program.build(options=options)
    log = program.get_build_info(device, cl.program_build_info.LOG) or ""
    notes = [ln for ln in log.splitlines() if "warning" in ln or "error" in ln]
    if any("changes the ABI" not in ln for ln in notes):
        warnings.warn(f"OpenCL compiler said:\n{log}", cl.CompilerWarning, stacklevel=3)


def _float4(point) -> np.ndarray:
    p = np.asarray(point, dtype=np.float64).reshape(3)
    return cl.cltypes.make_float4(float(p[0]), float(p[1]), float(p[2]), 0.0)


def _as_float4_rows(points) -> np.ndarray:
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
        self._programs: dict = {}
        self._kernels: dict = {}
        self._philox = None
        self._constants: dict = {}
        self.name = devices.describe(self.device)

    # ------------------------------------------------------------ programs and buffers
    def kernel(self, source: str, name: str, **defines) -> "cl.Kernel":
        """Kernel `name` of kernels/<source>.cl built with -D defines; built and fetched once."""
        options = tuple(f"-D{k}={v}" for k, v in sorted(defines.items()))
        key = (source, options, name)
        kern = self._kernels.get(key)
        if kern is None:
            program = self._programs.get((source, options))
            if program is None:
                program = cl.Program(self.context, kernel_source(source))
                try:
                    _build_quietly(program, list(options), self.device)
                except cl.RuntimeError as exc:
                    raise DeviceError(f"kernels/{source}.cl failed to build on {self.name} "
                                      f"with {list(options)}:\n{exc}") from exc
                self._programs[(source, options)] = program
            kern = self._kernels[key] = getattr(program, name)
        return kern

    def empty(self, shape, dtype=np.float32):
        return cla.empty(self.queue, shape, dtype, allocator=self.allocator)

    def from_numpy(self, array):
        return cla.to_device(self.queue, np.ascontiguousarray(array, dtype=np.float32),
                             allocator=self.allocator)

    def finish(self):
        """Wait for everything queued (for timing a stage)."""
        self.queue.finish()

    def _small(self, array, dtype=np.float32):
        """A small read-only input (taps, spots, axes) on the device, uploaded once per content:
        a stream of frames with the same geometry re-uses it instead of copying each frame."""
        host = np.ascontiguousarray(array, dtype=dtype)
        key = (host.shape, host.dtype.str, host.tobytes())
        buf = self._constants.pop(key, None)
        if buf is None:
            buf = cla.to_device(self.queue, host)
        self._constants[key] = buf  # most recently used last
        while len(self._constants) > 64:
            self._constants.pop(next(iter(self._constants)))
        return buf

    def groups(self, n: int, bytes_each: int, what: str) -> list[tuple[int, int]]:
        """Split n rows into consecutive groups whose buffer (bytes_each per row) fits under
        max_alloc_bytes."""
        per = self.max_alloc_bytes // max(int(bytes_each), 1)
        if per < 1:
            raise DeviceError(f"{what}: one row needs {bytes_each} bytes, more than this device "
                              f"allows in one buffer ({self.max_alloc_bytes} bytes). Fix: use "
                              "fewer bins, facets or grid cells per row")
        return [(i, min(i + per, n)) for i in range(0, n, per)]

    def _shrinking_on_oom(self, stage, *args):
        """Run a stage; if the device runs out of memory, free the pool, halve the chunk cap
        and retry, down to 1 MiB, then say what to reduce."""
        while True:
            try:
                return stage(*args)
            except (cl.MemoryError, cl.RuntimeError) as exc:
                if "OUT_OF" not in str(exc) and "ALLOCATION" not in str(exc):
                    raise
                self.allocator.free_held()
                if self.max_alloc_bytes <= 1 << 20:
                    raise DeviceError(f"{self.name} ran out of memory even in 1 MiB chunks "
                                      f"({exc}). Fix: reduce the grid, the number of bins or "
                                      "detectors, or the facet count") from exc
                self.max_alloc_bytes //= 2
                warnings.warn(f"device out of memory: retrying in chunks of at most "
                              f"{self.max_alloc_bytes} bytes", RuntimeWarning, stacklevel=3)

    def run(self, kernel, global_size, *args):
        """Enqueue with the local size left to the runtime (best on CPU devices)."""
        kernel.set_args(*[a.data if isinstance(a, cla.Array) else a for a in args])
        return cl.enqueue_nd_range_kernel(self.queue, kernel, global_size, None)

    # ------------------------------------------------------------ stages
    def simulate(self, facets: Facets, spots, laser, edge0, dpath, sigma_path, n_bins):
        return self._shrinking_on_oom(self._simulate, facets, spots, laser, edge0, dpath,
                                      sigma_path, n_bins)

    def _simulate(self, facets, spots, laser, edge0, dpath, sigma_path, n_bins):
        n_det, n_facets = len(spots), facets.count
        n_chunks = -(-n_facets // FACET_CHUNK)
        n_pad = n_chunks * FACET_CHUNK
        centres = _as_float4_rows(facets.centres)
        normals = _as_float4_rows(facets.normals)
        normals[:, 3] = facets.areas
        centres, normals = self.from_numpy(centres), self.from_numpy(normals)
        spots_buf = self._small(_as_float4_rows(spots))
        axis = self._small(np.stack([edge0, dpath], axis=1))
        paths_kernel = self.kernel("forward", "facet_paths", CHUNK=FACET_CHUNK)
        bins_kernel = self.kernel("forward", "pulse_bins", CHUNK=FACET_CHUNK)
        hist = self.empty((n_det, n_bins))
        spans = []
        for d0, d1 in self.groups(n_det, 4 * n_pad, "facet paths of one detector"):
            path = self.empty((d1 - d0, n_pad))
            weight = self.empty((d1 - d0, n_pad))
            ranges = self.empty((d1 - d0, n_chunks, 2))
            self.run(paths_kernel, (n_chunks, d1 - d0), centres, normals, np.int32(n_facets),
                     spots_buf, _float4(laser), np.int32(d0), path, weight, ranges)
            self.run(bins_kernel, (-(-n_bins // FORWARD_BLOCK), d1 - d0), path, weight, ranges,
                     np.int32(n_chunks), axis, np.float32(1.0 / (math.sqrt(2.0) * sigma_path)),
                     np.float32(REACH_SIGMAS * sigma_path), np.int32(n_bins), np.int32(d0), hist)
            r = ranges.get(self.queue).astype(np.float64)  # tiny (D, chunks, 2): validation
            spans.append(np.stack([r[..., 0].min(axis=1), r[..., 1].max(axis=1)], axis=1))
        return hist, np.concatenate(spans)

    def standard_normal(self, shape, seed):
        """Seeded N(0, 1) draws from Philox (counter-based: the same stream on every device).

        One generator per context (its programs build once); for each call it is re-keyed from
        the seed exactly as pyopencl keys a fresh PhiloxGenerator(seed=seed), so a seed always
        means the same noise, frame after frame.
        """
        if self._philox is None:
            self._philox = clrandom.PhiloxGenerator(self.context, seed=0)
        gen = self._philox
        draw = random.Random(seed)
        lo, hi = int(np.iinfo(np.int32).min), int(np.iinfo(np.int32).max)
        gen.key = [draw.randrange(lo, hi + 1) for _ in range(gen.key_length - 1)]
        gen.counter = [draw.randrange(lo, hi + 1) for _ in range(4)]
        with warnings.catch_warnings():  # pyopencl's own Random123 program: its build notes
            warnings.simplefilter("ignore", cl.CompilerWarning)
            return gen.normal(self.queue, shape, np.float32, allocator=self.allocator)

    def add_awgn(self, signal, normal, snr_db):
        n_rows, n_bins = signal.shape
        stats = self.row_stats(signal)
        out = self.empty(signal.shape)
        self.run(self.kernel("signal", "add_awgn"), (n_bins, n_rows), signal, normal, stats,
                 np.float32(10.0 ** (-snr_db / 10.0)), np.int32(n_bins), out)
        return out

    def gauss_filter(self, signal, taps):
        return self._shrinking_on_oom(self._gauss_filter, signal, taps)

    def _gauss_filter(self, signal, taps):
        n_rows, n_bins = signal.shape
        half = (len(taps) - 1) // 2
        space = "__constant" if 4 * len(taps) <= self.device.max_constant_buffer_size else "__global"
        defines = dict(HALF=half, TAPS_SPACE=space)
        pad_kernel = self.kernel("gauss_filter", "pad_rows", **defines)
        filter_kernel = self.kernel("gauss_filter", "gauss_filter", **defines)
        taps_buf = self._small(taps)
        # Zero margins: HALF bins before, HALF + a block after (the last block reads past the end).
        width = n_bins + 2 * half + FILTER_BLOCK
        out = self.empty(signal.shape)
        for r0, r1 in self.groups(n_rows, 4 * width, "a zero-padded histogram row"):
            padded = self.empty((r1 - r0, width))
            self.run(pad_kernel, (width, r1 - r0), signal, np.int32(n_bins), np.int32(r0), padded)
            self.run(filter_kernel, (-(-n_bins // FILTER_BLOCK), r1 - r0), padded, taps_buf,
                     np.int32(n_bins), np.int32(r0), out)
        return out

    def row_stats(self, signal):
        stats = self.empty((signal.shape[0], 2))
        self.run(self.kernel("signal", "row_stats"), (signal.shape[0],), signal,
                 np.int32(signal.shape[1]), stats)
        return stats

    def ellipse_score(self, signal, stats, spots, laser, path0, inv_dpath, grid: Grid, log_mode,
                      log_floor):
        return self._shrinking_on_oom(self._ellipse_score, signal, stats, spots, laser, path0,
                                      inv_dpath, grid, log_mode, log_floor)

    def _ellipse_score(self, signal, stats, spots, laser, path0, inv_dpath, grid, log_mode,
                       log_floor):
        nx, ny, nz = grid.shape
        n_det, n_bins = signal.shape
        kern = self.kernel("ellipse_score", "ellipse_score", N_DET=n_det,
                           LOG_MODE=int(bool(log_mode)), LOG_FLOOR=f"{log_floor:.9e}f")
        # float32 path lengths of ~10 m round to ~1e-6 m: ~0.003 of a 1 ps (0.3 mm) bin.
        axis = self._small(np.stack([path0, inv_dpath], axis=1))
        spots_buf = self._small(_as_float4_rows(spots))
        by_plane = nz > 1  # slabs of whole planes, or of rows of the single plane
        n, row_bytes = (nz, 4 * nx * ny) if by_plane else (ny, 4 * nx)
        slabs = []
        for a0, a1 in self.groups(n, row_bytes, "a row of the score map"):
            planes, rows = (a1 - a0, ny) if by_plane else (1, a1 - a0)
            score = self.empty((planes, rows, nx))
            self.run(kern, (-(-nx // 8), rows, planes), signal, stats, spots_buf,
                     _float4(laser), axis, np.int32(n_bins), _float4(grid.origin),
                     _float4(grid.step), np.int32(nx), np.int32(rows),
                     np.int32(0 if by_plane else a0), np.int32(a0 if by_plane else 0), score)
            slabs.append((a0, score))
        return ScoreMap(grid.shape, by_plane, slabs)

    def argmax(self, score: "ScoreMap"):
        """First maximum over the whole map (lowest flat index on ties), slab by slab."""
        if not isinstance(score, ScoreMap):
            score = ScoreMap.whole(score)
        kern = self.kernel("signal", "argmax_partial")
        best = (-1, -np.inf)
        for start, slab in score.slabs:
            n_cells = slab.size
            items = min(ARGMAX_ITEMS, n_cells)
            per_item = -(-n_cells // items)
            best_value = self.empty((items,))
            best_index = self.empty((items,), np.int32)
            self.run(kern, (items,), slab, np.int32(n_cells), np.int32(per_item), best_value,
                     best_index)
            values, indices = best_value.get(self.queue), best_index.get(self.queue)
            w = int(np.argmax(values))  # first maximum within the slab
            if values[w] > best[1]:  # strict: an earlier slab wins ties
                best = (start * score.cells_per_step + int(indices[w]), float(values[w]))
        return best

    def read_rows(self, score: "ScoreMap", iz, iy0, iy1):
        parts = []
        for start, slab in score.slabs:
            if score.by_plane:
                if start <= iz < start + slab.shape[0]:
                    return slab[iz - start, iy0:iy1].get(self.queue).astype(np.float64)
            else:
                lo, hi = max(iy0, start), min(iy1, start + slab.shape[1])
                if lo < hi:
                    parts.append(slab[0, lo - start:hi - start].get(self.queue))
        return np.concatenate(parts).astype(np.float64)

    def to_numpy(self, handle):
        if isinstance(handle, ScoreMap):
            return np.concatenate([slab.get(self.queue) for _, slab in handle.slabs],
                                  axis=0 if handle.by_plane else 1).astype(np.float64)
        return handle.get(self.queue).astype(np.float64)


class ScoreMap:
    """A grid's scores on the device, in one or more slabs of planes (or of rows)."""

    def __init__(self, shape, by_plane, slabs):
        self.shape = shape  # (nx, ny, nz)
        self.by_plane = by_plane
        self.slabs = slabs  # [(first plane or row, array)]
        nx, ny, _ = shape
        self.cells_per_step = nx * ny if by_plane else nx

    @classmethod
    def whole(cls, array) -> "ScoreMap":
        """A (nz, ny, nx) device array as a one-slab map."""
        nz, ny, nx = array.shape
        return cls((nx, ny, nz), True, [(0, array)])

    @property
    def size(self) -> int:
        return self.shape[0] * self.shape[1] * self.shape[2]

_shared: dict = {}


def get_runtime(device=None) -> Runtime:
    """A Runtime per device spec, created once and reused (programs stay built)."""
    key = device if device is None or isinstance(device, str) else id(device)
    runtime = _shared.get(key)
    if runtime is None:
        runtime = _shared[key] = Runtime(device)
    return runtime
