"""Run every kernel of kernels/*.cl on tiny inputs, for the oclgrind OpenCL simulator.

Meant to run under oclgrind; scripts/oclgrind_check.sh sets the environment (only the
"Oclgrind Simulator" device visible, data-race detection on, OCLGRIND_LOG) and reads the logs.
oclgrind checks every memory access for out-of-bounds reads and writes and every pair of
accesses for data races; it reports into its log and never changes an exit status. This
script's job is to reach every kernel, every build-option variant and every branch that decides
an address (partial last blocks, paths outside the record, chunked groups and slabs), and to
compare the results loosely with the float64 NumPy twins so that the run means something (a
kernel that silently wrote nothing would pass oclgrind's checks). It fails if a kernel of
kernels/*.cl was never run, or if anything issued a warning (e.g. a compiler note).

oclgrind opens OCLGRIND_LOG afresh for every OpenCL context, so this script gives each
Runtime (each its own context) its own log: OCLGRIND_LOG + "." + a label (main, chunked).

Exit status: 0 if every comparison passed, 1 otherwise (oclgrind's findings are only in the
logs), 2 if the device is not oclgrind.

Usage: python scripts/oclgrind_check.py [--canary] [--device SPEC]
  default: the oclgrind device;
  --canary: only run a kernel with a known race and out-of-bounds write (in two contexts);
  --device: any other device, e.g. --device 0:0 for a quick native run.
"""
from __future__ import annotations

import argparse
import math
import os
import re
import sys
import time
import warnings
from pathlib import Path

import numpy as np

def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default=None,
                        help="device spec (default: the oclgrind device, required)")
    parser.add_argument("--canary", action="store_true",
                        help="only run a kernel with a known race and out-of-bounds write")
    return parser.parse_args(argv)


ARGS = parse_args() if __name__ == "__main__" else parse_args([])
# Build every program afresh, so that oclgrind's compiler messages are what this run sees.
# (oclgrind 21.10 evaluates integer clamp/min/max with scalar bounds wrongly; the kernels use
# vector bounds, see ellipse_score.cl.)
os.environ.setdefault("PYOPENCL_NO_CACHE", "1")

import nlos_cl as nl  # noqa: E402  (after the environment above is set)
from nlos_cl import reference as ref  # noqa: E402
from nlos_cl.reference import NumpyBackend  # noqa: E402
from nlos_cl.runtime import ARGMAX_ITEMS, FACET_CHUNK, FILTER_BLOCK, Runtime  # noqa: E402

C = nl.SPEED_OF_LIGHT
KERNELS_DIR = Path(__file__).resolve().parent.parent / "kernels"
FAILURES: list[str] = []


def check(ok, what: str, detail: str = "") -> None:
    ok = bool(ok)
    print(f"  [{'ok' if ok else 'FAIL'}] {what}{' (' + detail + ')' if detail else ''}",
          flush=True)
    if not ok:
        FAILURES.append(f"{what} {detail}".strip())


def rel_err(a, b) -> float:
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    scale = np.abs(b).max()
    return float(np.abs(a - b).max() / scale) if scale > 0 else float(np.abs(a).max())


class Stage:
    """Prints a header and the stage's wall time."""

    def __init__(self, name):
        self.name = name

    def __enter__(self):
        print(f"== {self.name}", flush=True)
        self.t = time.perf_counter()

    def __exit__(self, *exc):
        print(f"   {time.perf_counter() - self.t:.1f} s", flush=True)


def window_around(setup, mesh, dt_s, margin_m=0.1) -> nl.TimeAxis:
    """A short time axis covering every hidden path the target can produce, plus a margin."""
    pts = mesh.vertices
    r1 = np.linalg.norm(pts - setup.laser_spot, axis=1)
    paths = r1[None, :] + np.linalg.norm(pts[None] - setup.detector_spots[:, None], axis=2)
    lo, hi = paths.min() - margin_m, paths.max() + margin_m
    t0 = (2 * setup.device_distance_m + lo) / C + setup.pulse.peak_delay_s
    return nl.TimeAxis(t0, dt_s, int(math.ceil((hi - lo) / (C * dt_s))))


# ---------------------------------------------------------------------------- stages

def forward(rt, twin, scene, axis, chunk_rt):
    """forward.cl: facet_paths + pulse_bins, whole and in one-detector groups."""
    with Stage("forward (facet_paths, pulse_bins)"):
        facets = scene.facets()
        n_pad = -(-facets.count // FACET_CHUNK) * FACET_CHUNK
        print(f"  {facets.count} facets ({n_pad // FACET_CHUNK} chunks), "
              f"{scene.setup.n_detectors} detectors, {axis.n_bins} bins")
        check(facets.count % FACET_CHUNK != 0, "facet count leaves a partial last chunk",
              f"{facets.count} facets")
        check(axis.n_bins % 15 != 0, "bin count leaves a partial last 15-bin block",
              f"{axis.n_bins} bins")
        dev = nl.simulate(scene, axis, backend=rt)
        ref_sig = nl.simulate(scene, axis, backend=twin)
        a, b = dev.histograms().data, ref_sig.histograms().data
        check(b.max() > 0 and np.all(b.max(axis=1) > 0), "twin histograms are non-zero")
        err = rel_err(a, b)
        check(err < 2e-3, "simulate matches the NumPy twin", f"rel err {err:.2e}")

        # Direct Runtime.simulate: the facet path range (chunk_range) against the twin.
        args = (facets, scene.setup.detector_spots, scene.setup.laser_spot,
                ref_sig.layout.calibration.offsets(scene.setup.n_detectors) + C * axis.t0_s,
                np.full(scene.setup.n_detectors, C * axis.dt_s),
                C * scene.setup.pulse.sigma_s, axis.n_bins)
        _, span_dev = rt.simulate(*args)
        _, span_ref = twin.simulate(*args)
        check(np.allclose(span_dev, span_ref, atol=1e-5), "facet path range matches the twin",
              f"max diff {np.abs(span_dev - span_ref).max():.1e} m")

        # Chunked: a cap that holds exactly one detector's path row per group.
        chunk_rt.max_alloc_bytes = 4 * n_pad
        groups = chunk_rt.groups(scene.setup.n_detectors, 4 * n_pad, "facet paths")
        check(len(groups) == scene.setup.n_detectors, "forward runs in one-detector groups",
              f"{len(groups)} groups")
        split = nl.simulate(scene, axis, backend=chunk_rt).histograms().data
        check(np.array_equal(a, split), "grouped simulate is bit-identical to the whole run")
    return dev


def noise(rt, signals):
    """pyopencl's Philox (clrandom) + signal.cl: row_stats, add_awgn."""
    with Stage("noise (clrandom Philox, row_stats, add_awgn)"):
        shape = signals.layout.data.shape
        normal = rt.to_numpy(rt.standard_normal(shape, seed=3))
        again = rt.to_numpy(rt.standard_normal(shape, seed=3))
        check(np.array_equal(normal, again), "standard_normal is seeded (same seed, same draws)")
        check(abs(normal.mean()) < 0.3 and abs(normal.std() - 1) < 0.3,
              "standard_normal looks standard normal",
              f"mean {normal.mean():.3f} std {normal.std():.3f} over {normal.size}")
        host = rt.to_numpy(signals.handle)
        stats = rt.to_numpy(rt.row_stats(signals.handle))
        check(np.allclose(stats, ref.row_stats(host), rtol=1e-5, atol=0),
              "row_stats matches the twin")
        noisy = nl.add_noise(signals, snr_db=10.0, seed=3, backend=rt)
        twin = ref.add_awgn(host, normal, 10.0)
        err = rel_err(rt.to_numpy(noisy.handle), twin)
        check(err < 1e-5, "add_noise (add_awgn) matches the twin", f"rel err {err:.2e}")
    return noisy


def gauss(rt, signals, chunk_rt):
    """gauss_filter.cl: pad_rows + gauss_filter, __constant and __global taps, row groups."""
    with Stage("gauss_filter (pad_rows, gauss_filter)"):
        axis = signals.layout.time_axis
        h_s = 0.65e-9
        taps = ref.gauss_taps(h_s, axis.dt_s)
        half = (len(taps) - 1) // 2
        host = rt.to_numpy(signals.handle).astype(np.float32)
        n_rows, n_bins = host.shape
        print(f"  {n_rows} rows x {n_bins} bins, {len(taps)} taps")
        filtered = nl.gauss_filter(signals, h_s, backend=rt)
        out = rt.to_numpy(filtered.handle)
        err = rel_err(out, ref.gauss_filter(host, taps))
        check(err < 1e-5, "gauss_filter (__constant taps) matches the twin", f"rel err {err:.2e}")

        # TAPS_SPACE=__global is chosen only for > 16k taps on oclgrind (64 KiB of constant
        # memory): build that variant directly and run it exactly as Runtime.gauss_filter does.
        defines = dict(HALF=half, TAPS_SPACE="__global")
        width = n_bins + 2 * half + FILTER_BLOCK
        padded = rt.empty((n_rows, width))
        glob = rt.empty((n_rows, n_bins))
        rt.run(rt.kernel("gauss_filter", "pad_rows", **defines), (width, n_rows),
               signals.handle, np.int32(n_bins), np.int32(0), padded)
        rt.run(rt.kernel("gauss_filter", "gauss_filter", **defines),
               (-(-n_bins // FILTER_BLOCK), n_rows), padded, rt.from_numpy(taps),
               np.int32(n_bins), np.int32(0), glob)
        check(np.array_equal(rt.to_numpy(glob), out), "__global taps give the same result")

        # Record lengths around the 32-output block: whole blocks, one short block, and a
        # filter window (61 taps) longer than the record (40 bins).
        rng = np.random.default_rng(1)
        for n, half_bins in ((4 * FILTER_BLOCK, 3), (10, 3), (40, 30)):
            data = rng.standard_normal((2, n))
            taps_n = ref.gauss_taps(half_bins * axis.dt_s, axis.dt_s)
            got = rt.to_numpy(rt.gauss_filter(rt.from_numpy(data), taps_n))
            err = rel_err(got, ref.gauss_filter(data.astype(np.float32), taps_n))
            check(err < 1e-5, f"gauss_filter on {n} bins with {len(taps_n)} taps matches the "
                  "twin", f"rel err {err:.2e}")

        # Row groups: a cap of two padded rows per group (3 rows -> groups of 2 and 1).
        chunk_rt.max_alloc_bytes = 2 * 4 * width
        n_groups = len(chunk_rt.groups(n_rows, 4 * width, "a zero-padded row"))
        check(n_groups == -(-n_rows // 2), "gauss_filter runs in two-row groups",
              f"{n_groups} groups")
        split = chunk_rt.to_numpy(chunk_rt.gauss_filter(chunk_rt.from_numpy(host), taps))
        check(np.array_equal(split, out), "gauss_filter in row groups is bit-identical")
    return filtered


def score(rt, twin, filtered, chunk_rt):
    """ellipse_score.cl (product and log mode; plane and volume; whole and in slabs), and
    signal.cl: argmax_partial through Runtime.argmax / nl.locate."""
    hist = filtered.histograms()
    truth = np.asarray(hist.truth)
    # nx = 21: two whole 8-cell blocks and a partial one; nx = 16: whole blocks only.
    grids = {
        "plane 21x5x1": nl.Grid((truth[0] - 0.2, truth[1] - 0.08, 0.0), (0.02, 0.02, 0.02),
                                (21, 5, 1)),
        "volume 16x4x3": nl.Grid((truth[0] - 0.15, truth[1] - 0.06, -0.04), (0.02, 0.04, 0.04),
                                 (16, 4, 3)),
    }
    with Stage("ellipse_score + argmax_partial (via nl.locate)"):
        for gname, grid in grids.items():
            nx, ny, nz = grid.shape
            by_plane = nz > 1
            for log_mode in (False, True):
                label = f"{gname} {'log' if log_mode else 'product'}"
                a = nl.locate(hist, grid, log_mode=log_mode, return_map=True, backend=rt)
                b = nl.locate(hist, grid, log_mode=log_mode, return_map=True, backend=twin)
                am, bm = a.score_map, b.score_map
                check(am.shape == (nz, ny, nx), f"{label}: map shape", str(am.shape))
                if log_mode:
                    lit = bm > 3 * np.log(1e-4)
                    err = float(np.abs(am - bm)[lit].max()) if lit.any() else float("nan")
                    check(lit.mean() > 0.5 and err < 1e-2, f"{label}: matches the twin",
                          f"abs err {err:.2e} on {lit.sum()}/{lit.size} lit cells")
                else:
                    err = rel_err(am, bm)
                    check(bm.max() > 0 and err < 1e-2, f"{label}: matches the twin",
                          f"rel err {err:.2e}")
                check(np.linalg.norm(a.position - b.position) <= max(grid.step),
                      f"{label}: located where the twin locates",
                      f"{np.round(a.position, 4).tolist()} vs {np.round(b.position, 4).tolist()}")

                # Slabs: two rows (plane) or two planes (volume) per slab.
                row_bytes = 4 * nx * (ny if by_plane else 1)
                chunk_rt.max_alloc_bytes = 2 * row_bytes
                c = nl.locate(hist, grid, log_mode=log_mode, return_map=True, backend=chunk_rt)
                sig = chunk_rt.from_numpy(hist.data / np.abs(hist.data).max())
                path0, dpath = hist.score_axis()
                handle = chunk_rt.ellipse_score(sig, chunk_rt.row_stats(sig),
                                                hist.detector_spots, hist.laser_spot, path0,
                                                1.0 / dpath, grid, log_mode, 1e-6)
                n_slabs = len(handle.slabs)
                check(n_slabs == -(-(nz if by_plane else ny) // 2),
                      f"{label}: scored in slabs of {'planes' if by_plane else 'rows'}",
                      f"{n_slabs} slabs")
                check(np.array_equal(c.score_map, am) and np.array_equal(c.position, a.position),
                      f"{label}: slabs are bit-identical to one piece")
                flat, best = chunk_rt.argmax(handle)
                check(flat == int(np.argmax(am.reshape(-1))) and best == am.max(),
                      f"{label}: argmax over slabs", f"flat {flat}")

    with Stage("ellipse_score on a wide grid (paths below and above the record)"):
        # Cells whose ellipse path lies outside the record: the clamped gathers must stay in
        # bounds and give 0.
        grid = nl.Grid((2.0, 0.3, 0.0), (0.25, 0.25, 0.25), (19, 15, 1))
        path0, dpath = hist.score_axis()
        cells = grid.cell_centres().reshape(-1, 3)
        r1 = np.linalg.norm(cells - hist.laser_spot, axis=1)
        u = (r1[None] + np.linalg.norm(cells[None] - hist.detector_spots[:, None], axis=2)
             - path0[:, None]) / dpath[:, None]
        n_bins = hist.data.shape[1]
        check((u < -1).any() and (u > n_bins).any(), "the grid reaches past both ends of the "
              "record", f"fractional bins {u.min():.0f} .. {u.max():.0f} of {n_bins}")
        data = hist.data / np.abs(hist.data).max()
        sig = rt.from_numpy(data)
        for log_mode in (False, True):
            handle = rt.ellipse_score(sig, rt.row_stats(sig), hist.detector_spots,
                                      hist.laser_spot, path0, 1.0 / dpath, grid, log_mode, 1e-6)
            got = rt.to_numpy(handle)
            twin_map = ref.ellipse_score(data.astype(np.float32).astype(np.float64),
                                         ref.row_stats(data), hist.detector_spots,
                                         hist.laser_spot, path0, 1.0 / dpath, grid, log_mode,
                                         1e-6)
            err = float(np.abs(got - twin_map).max()) if log_mode else rel_err(got, twin_map)
            floor = hist.n_detectors * math.log(1e-6) if log_mode else 0.0
            n_lit = int((twin_map > floor).sum())
            check(np.isfinite(got).all() and err < 1e-2 and 0 < n_lit < twin_map.size,
                  f"wide grid {'log' if log_mode else 'product'}: matches the twin",
                  f"{'abs' if log_mode else 'rel'} err {err:.2e}, {n_lit}/{twin_map.size} "
                  "cells above the floor")

    with Stage("argmax_partial (ties, more cells than work items)"):
        tie = np.zeros((1, 7, 9), np.float32)
        tie[0, 2, 3] = tie[0, 5, 8] = 3.0  # a tie: the lower flat index must win
        tie[0, 6, 0] = 2.0
        check(rt.argmax(rt.from_numpy(tie)) == (2 * 9 + 3, 3.0), "first maximum wins a tie")
        # 1500 cells: per_item 2, so the last work items get empty ranges.
        many = np.random.default_rng(5).random((1, 30, 50)).astype(np.float32)
        got = rt.argmax(rt.from_numpy(many))
        check(got == (int(np.argmax(many)), float(many.max())),
              f"argmax over {many.size} cells with {ARGMAX_ITEMS} work items", str(got))


def probes(rt):
    """probes.cl: exp_probe, fma_probe, copy_probe with a tiny ITERS."""
    with Stage("probes (exp_probe, fma_probe, copy_probe)"):
        iters, items, a = 3, 16, 0.5
        out = rt.empty((items,))
        rt.run(rt.kernel("probes", "exp_probe", ITERS=iters), (items,), out, np.float32(a))
        x0 = a + np.arange(8) * 1e-3
        xs = np.stack([x0 + 0.1 * j for j in range(8)])
        for _ in range(iters):
            xs = np.exp(-xs)
        got = out.get()
        check(np.allclose(got, xs.sum(), rtol=1e-5), "exp_probe matches NumPy",
              f"{got[0]:.6f} vs {xs.sum():.6f}")

        rt.run(rt.kernel("probes", "fma_probe", ITERS=iters), (items,), out, np.float32(a))
        xs = np.stack([np.full(8, a) + j for j in range(12)])
        for _ in range(iters):
            xs = xs * 0.999 + 1e-3
        got = out.get()
        check(np.allclose(got, xs.sum(), rtol=1e-5), "fma_probe matches NumPy",
              f"{got[0]:.4f} vs {xs.sum():.4f}")

        src = np.random.default_rng(2).random((items, 4)).astype(np.float32)
        dst = rt.empty((items, 4))
        rt.run(rt.kernel("probes", "copy_probe"), (items,), rt.from_numpy(src), dst)
        check(np.array_equal(dst.get(), src), "copy_probe copies")


# oclgrind opens (and truncates) OCLGRIND_LOG once per OpenCL context, each with its own file
# position, so a second context overwrites what the first logged. Every Runtime (a context of
# its own) therefore gets its own file, OCLGRIND_LOG + "." + label; the wrapper reads them all.
LOG_BASE = os.environ.get("OCLGRIND_LOG")
LOGS: list[str] = []


def new_runtime(label, *args, **kwargs) -> "TracingRuntime":
    if LOG_BASE:
        os.environ["OCLGRIND_LOG"] = f"{LOG_BASE}.{label}"
        LOGS.append(os.environ["OCLGRIND_LOG"])
    try:
        return TracingRuntime(*args, **kwargs)
    finally:
        if LOG_BASE:
            os.environ["OCLGRIND_LOG"] = LOG_BASE


class TracingRuntime(Runtime):
    """A Runtime that records which kernels (and build-option variants) were fetched."""

    used: set = set()

    def kernel(self, source, name, **defines):
        kern = super().kernel(source, name, **defines)
        TracingRuntime.used.add((source, name, tuple(sorted(defines.items()))))
        return kern


def all_kernels() -> set:
    """(source, kernel name) of every __kernel in the checkout's kernels/*.cl."""
    found = set()
    for path in sorted(KERNELS_DIR.glob("*.cl")):
        text = re.sub(r"//[^\n]*|/\*.*?\*/", "", path.read_text(), flags=re.S)
        found |= {(path.stem, m) for m in re.findall(r"__kernel\s+void\s+(\w+)", text)}
    return found


CANARY = r"""
__kernel void canary(__global float *out, const int n)
{
    const int i = get_global_id(0);
    out[0] = (float)i;     // every work item writes out[0], each a different value: a data race
    out[n + i] = 1.0f;     // past the end of the n-float buffer: an invalid write
}
"""


def canary(rt) -> int:
    """Run a kernel with a known data race and a known out-of-bounds write, in this context
    and in a second one, so that the wrapper can confirm that oclgrind's checks are on and
    that every context's findings reach their own log."""
    cl = nl.runtime.cl
    for runtime in (rt, new_runtime("canary2", rt.device)):
        program = cl.Program(runtime.context, CANARY).build()
        out = runtime.empty((4,))
        runtime.run(program.canary, (4,), out, np.int32(4))
        runtime.finish()
    print("oclgrind_check: canary ran (each log must show an invalid write and a data race)")
    return 0


def main() -> int:
    args = ARGS
    start = time.perf_counter()
    rt = new_runtime("canary" if args.canary else "main", args.device or "oclgrind")
    print(f"device: {rt.name}")
    if LOG_BASE:
        print(f"oclgrind logs: {LOG_BASE}.<context> (one per OpenCL context)")
    if args.device is None and "oclgrind" not in rt.name.lower():
        print("oclgrind_check: not running on oclgrind; run scripts/oclgrind_check.sh",
              file=sys.stderr)
        return 2
    if args.canary:
        return canary(rt)
    twin = NumpyBackend()
    # One Runtime with a tiny allocation cap for every chunked path; each stage sets the cap.
    chunk_rt = new_runtime("chunked", rt.device, max_alloc_bytes=1 << 10)

    with warnings.catch_warnings(record=True) as caught:
        # Every warning counts: a compiler note from oclgrind's clang, a cut time window, ...
        warnings.simplefilter("always")
        scene = nl.paper_scene(facet_size_m=0.1)
        axis = window_around(scene.setup, scene.target.mesh, 50e-12)
        signals = forward(rt, twin, scene, axis, chunk_rt)
        noisy = noise(rt, signals)
        gauss(rt, noisy, chunk_rt)
        # Score the clean filtered signal: a sharp, well-defined peak to compare with the twin.
        clean = nl.gauss_filter(signals, 0.65e-9, backend=rt)
        score(rt, twin, clean, chunk_rt)
        probes(rt)
        rt.finish()
        chunk_rt.finish()
    print("== coverage")
    for w in caught:
        check(False, "no warning while running", f"{w.category.__name__}: {w.message}")
    ran = {(src, name) for src, name, _ in TracingRuntime.used}
    missing = sorted(all_kernels() - ran)
    check(not missing, f"every kernel of kernels/*.cl ran ({len(ran)} kernels, "
          f"{len(TracingRuntime.used)} build variants)",
          "missing: " + ", ".join(f"{s}.cl:{n}" for s, n in missing) if missing else "")

    print(f"oclgrind_check: {len(FAILURES)} failed comparison(s), "
          f"{time.perf_counter() - start:.1f} s")
    for f in FAILURES:
        print(f"  FAIL {f}")
    return 1 if FAILURES else 0


if __name__ == "__main__":
    sys.exit(main())
