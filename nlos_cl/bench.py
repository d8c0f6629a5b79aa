"""`nlos-cl bench`: every kernel against its NumPy twin and against this device's own limits.

Kernel times are medians of >= 5 runs after a warm-up (the first call, which builds the
programs, is reported separately as build time). Twin times are medians of fewer runs when a
run takes seconds, or extrapolated from a stated fraction of the work where it would take
minutes. Throughput is counted in the currency a kernel spends (erf lanes, FMAs, cell-detector
evaluations); the fraction of limit compares it with tiny probe kernels run first on the same
device: float8 exp throughput, FMA throughput, copy bandwidth. Timings are reported, never
asserted.
"""
from __future__ import annotations

import json
import math
import statistics
import time
import tracemalloc
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from . import pipeline as pl
from . import reference as ref
from .histograms import Grid, TimeAxis
from .reference import NumpyBackend
from .runtime import FORWARD_BLOCK, FILTER_BLOCK, get_runtime
from .scene import SPEED_OF_LIGHT, Scene, Target, box, paper_scene, paper_setup

C = SPEED_OF_LIGHT


@dataclass
class Row:
    case: str
    size: str
    work: float  # problem size for the plot (bins x facets, cells x detectors, ...)
    kernel_s: float
    twin_s: float
    build_s: float
    throughput: float
    unit: str
    fraction: float
    bound: str
    peak_host_mb: float
    note: str = ""
    fractions: dict = field(default_factory=dict)

    @property
    def ratio(self) -> float:
        return self.twin_s / self.kernel_s


def _median_time(fn, repeats, finish):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        finish()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def measure_limits(rt, smoke=False) -> dict:
    """Device limits from probe kernels: exp lanes/s, FMA/s, copy bytes/s (read + write)."""
    iters = 256 if smoke else 2048
    items = 4 * rt.device.max_compute_units * 256
    out = rt.empty((items,))
    limits = {}
    for name, per_iter in (("exp_probe", 64), ("fma_probe", 96)):
        kern = rt.kernel("probes", name, ITERS=iters)
        run = lambda: rt.run(kern, (items,), out, np.float32(0.5))  # noqa: E731
        run()
        rt.finish()
        t = _median_time(run, 5, rt.finish)
        limits["exp_per_s" if name == "exp_probe" else "fma_per_s"] = items * iters * per_iter / t
    n = (1 << 20) if smoke else (1 << 24)  # float4s: 16 MiB or 256 MiB per buffer
    src, dst = rt.empty((n, 4)), rt.empty((n, 4))
    kern = rt.kernel("probes", "copy_probe")
    run = lambda: rt.run(kern, (n,), src, dst)  # noqa: E731
    run()
    rt.finish()
    limits["bytes_per_s"] = 2 * 16 * n / _median_time(run, 5, rt.finish)
    return limits


def _fraction(limits, exp_ops=0.0, fmas=0.0, nbytes=0.0, seconds=1.0):
    fr = {"exp": exp_ops / seconds / limits["exp_per_s"],
          "fma": fmas / seconds / limits["fma_per_s"],
          "bandwidth": nbytes / seconds / limits["bytes_per_s"]}
    bound = max(fr, key=fr.get)
    return fr[bound], bound, fr


ANALYSIS = """## Where each kernel stands

- **forward** (`pulse_bins`) spends its time in erf: one float16 erf (Abramowitz & Stegun
  7.1.26: an exp, a division and a degree-5 polynomial, about 2 exp) per facet within reach of
  a 15-bin block. Against the exp probe it reaches 15-30 %, i.e. roughly 30-60 % of what an
  erf made of exp could reach. Left on the table: facets in a chunk that overlaps a block but
  lie outside its reach (~25 % of the facet tests at 64-facet chunks), and the loop is serial
  per work item. Sorting facets by path per detector would remove the waste.
- **gauss_filter** is load-bound before it is FMA-bound: per tap, two unaligned 16-float loads
  per two 16-float FMAs, so it sits at 25-35 % of the FMA probe. Exploiting the symmetric taps
  (add the two mirrored samples, then one FMA) or an FFT for long windows would lift it.
- **ellipse_score** is bound by its gathers: per cell and detector two 8-lane gathers made of
  scalar loads (PoCL emits no hardware gathers). The fraction column compares only its sqrt
  (and log) with the exp probe, which is not what limits it.
- Timings on a shared 2-core machine move by +-30 % from run to run (the same kernel measured
  2.6-5.0 ms in one session); compare ratios taken in one run.
- **pipeline** and **stream** include the host: validation, the tiny argmax and neighbourhood
  reads, and Python. At 3 x 4,096 bins and 512 x 512 cells about two thirds of a frame is host
  overhead, one third kernels (ellipse_score ~1.3 ms).
"""


class Bench:
    def __init__(self, device=None, smoke=False, progress=print):
        self.rt = get_runtime(device)
        self.twin = NumpyBackend()
        self.smoke = smoke
        self.say = progress
        self.limits = measure_limits(self.rt, smoke)
        self.rows: list[Row] = []

    # --------------------------------------------------------------- timing helpers
    def _time(self, kernel_fn, twin_fn, twin_repeats=3, twin_scale=1.0):
        """(kernel median, twin median, build time, peak host MiB). Host memory is traced on
        the warm-up and twin runs only: tracing taxes every Python allocation, so the timed
        kernel runs go untraced."""
        tracemalloc.start()
        tracemalloc.reset_peak()
        start = time.perf_counter()
        kernel_fn()
        self.rt.finish()
        first = time.perf_counter() - start
        twin_s = _median_time(twin_fn, twin_repeats, lambda: None) * twin_scale
        peak = tracemalloc.get_traced_memory()[1] / 2 ** 20
        tracemalloc.stop()
        kernel_s = _median_time(kernel_fn, 5, self.rt.finish)
        return kernel_s, twin_s, max(first - kernel_s, 0.0), peak

    def _add(self, row: Row):
        self.rows.append(row)
        self.say(f"  {row.case:<14} {row.size:<44} kernel {row.kernel_s * 1e3:9.2f} ms  "
                 f"twin {row.twin_s * 1e3:10.1f} ms  x{row.ratio:6.1f}  "
                 f"{100 * row.fraction:5.1f}% of {row.bound}")

    # --------------------------------------------------------------- cases
    def forward(self, label, scene, axis):
        setup = scene.setup
        facets = scene.facets()
        cal = pl.PathCalibration.for_setup(setup)
        edge0 = cal.offsets(setup.n_detectors) + C * axis.t0_s
        dpath = np.full(setup.n_detectors, C * axis.dt_s)
        sigma = C * setup.pulse.sigma_s
        args = (facets, setup.detector_spots, setup.laser_spot, edge0, dpath, sigma, axis.n_bins)
        k, t, b, mem = self._time(lambda: self.rt.simulate(*args), lambda: self.twin.simulate(*args),
                                  twin_repeats=1 if facets.count > 50_000 else 3)
        lanes = self._erf_lanes(facets, setup, edge0, dpath, sigma, axis.n_bins)
        frac, bound, fr = _fraction(self.limits, exp_ops=lanes, seconds=k)
        self._add(Row("forward", f"{label}: {facets.count} facets x {setup.n_detectors} det x "
                      f"{axis.n_bins} bins", facets.count * setup.n_detectors * axis.n_bins,
                      k, t, b, lanes / k / 1e9, "G erf lanes/s", frac, bound, mem,
                      "erf measured against the exp probe: erf costs ~2 exp, so the true "
                      "fraction is higher", fr))

    @staticmethod
    def _erf_lanes(facets, setup, edge0, dpath, sigma, n_bins):
        """erf lanes pulse_bins evaluates: 16 per (15-bin block, facet within reach)."""
        path, weight = ref.facet_paths(facets.centres, facets.normals, facets.areas,
                                       setup.detector_spots, setup.laser_spot)
        reach = ref.REACH_SIGMAS * sigma
        total = 0
        starts = np.arange(0, n_bins, FORWARD_BLOCK)
        for d in range(len(path)):
            s = np.sort(path[d][weight[d] > 0])
            base = edge0[d] + dpath[d] * starts
            lo = np.searchsorted(s, base - reach)
            hi = np.searchsorted(s, base + dpath[d] * FORWARD_BLOCK + reach, side="right")
            total += int((hi - lo).sum())
        return 16.0 * total

    def gauss_filter(self, label, data, dt, h=0.65e-9):
        taps = ref.gauss_taps(h, dt)
        dev = self.rt.from_numpy(data)
        k, t, b, mem = self._time(lambda: self.rt.gauss_filter(dev, taps),
                                  lambda: ref.gauss_filter(data, taps))
        rows, n = data.shape
        fmas = rows * (-(-n // FILTER_BLOCK) * FILTER_BLOCK) * len(taps)
        frac, bound, fr = _fraction(self.limits, fmas=fmas, seconds=k)
        self._add(Row("gauss_filter", f"{label}: {rows} x {n} bins, {len(taps)} taps",
                      rows * n * len(taps), k, t, b, fmas / k / 1e9, "G FMA/s", frac, bound,
                      mem, "", fr))

    def ellipse_score(self, label, signal, spots, grid, log_mode=False, twin_detectors=None):
        n_det = len(signal)
        path0 = np.full(n_det, 7.0)
        inv_dp = np.full(n_det, 1.0 / (C * 10e-12))
        laser = np.zeros(3)
        dev = self.rt.from_numpy(signal)
        stats_dev = self.rt.row_stats(dev)
        stats = ref.row_stats(signal)
        sub = twin_detectors or n_det
        run_k = lambda: self.rt.ellipse_score(dev, stats_dev, spots, laser, path0, inv_dp, grid,  # noqa: E731
                                              log_mode, ref.LOG_FLOOR)
        run_t = lambda: ref.ellipse_score(signal[:sub], stats[:sub], spots[:sub], laser,  # noqa: E731
                                          path0[:sub], inv_dp[:sub], grid, log_mode, ref.LOG_FLOOR)
        k, t, b, mem = self._time(run_k, run_t, twin_repeats=1 if grid.n_cells * sub > 5e6 else 3,
                                  twin_scale=n_det / sub)
        evals = grid.n_cells * n_det
        transcendental = evals * (2 if log_mode else 1)  # sqrt (+ log)
        frac, _, fr = _fraction(self.limits, exp_ops=transcendental,
                                nbytes=4 * grid.n_cells, seconds=k)
        bound = "gathers (fraction: sqrt/log vs exp)"
        nx, ny, nz = grid.shape
        size = f"{label}: {nx}x{ny}" + (f"x{nz}" if nz > 1 else "") + f" cells x {n_det} det"
        note = (f"twin timed on {sub} of {n_det} detectors, scaled" if sub != n_det else "")
        self._add(Row("ellipse_score", size + (" (log)" if log_mode else ""), evals, k, t, b,
                      evals / k / 1e9, "G cell-det/s", frac, bound, mem, note, fr))

    def pipeline(self, label, scene, axis, grid):
        def run(backend):
            s = pl.simulate(scene, axis, backend=backend)
            f = pl.gauss_filter(pl.add_noise(s, 10.0, 0))
            return pl.locate(f, grid)
        k, t, b, mem = self._time(lambda: run(self.rt), lambda: run(self.twin), twin_repeats=1)
        self._add(Row("pipeline", f"{label}: simulate, noise, filter, locate", 1, k, t, b,
                      1 / k, "localizations/s", float("nan"), "-", mem, "", {}))

    def stream(self, label, frames, grid, twin_frames):
        scene = paper_scene(facet_size_m=0.02)
        axis = TimeAxis(2 * 20 / C, 10e-12, 4096)
        clean = pl.simulate(scene, axis, backend=self.rt)
        clean_twin = pl.upload(clean.histograms(), self.twin)

        def run(signals, n):
            for i in range(n):
                pl.locate(pl.gauss_filter(pl.add_noise(signals, 10.0, i)), grid)
        tracemalloc.start()
        run(clean, 2)  # warm-up: builds
        self.rt.finish()
        start = time.perf_counter()
        run(clean_twin, twin_frames)
        t = (time.perf_counter() - start) / twin_frames
        mem = tracemalloc.get_traced_memory()[1] / 2 ** 20
        tracemalloc.stop()
        start = time.perf_counter()
        run(clean, frames)
        self.rt.finish()
        k = (time.perf_counter() - start) / frames
        nx, ny, _ = grid.shape
        self._add(Row("stream", f"{label}: {frames} frames, 3 x 4096 bins, {nx}x{ny} cells",
                      frames, k, t, 0.0, 1 / k, "localizations/s", float("nan"), "-", mem,
                      f"per frame; twin timed on {twin_frames} frames", {}))

    # --------------------------------------------------------------- the suite
    def run_all(self):
        smoke = self.smoke
        s = 1 if not smoke else 0
        paper = paper_scene(facet_size_m=0.01 if s else 0.05)
        self.say("forward")
        demo_axis = (TimeAxis(2 * 20 / C, 1e-12, 60_000) if s
                     else TimeAxis(2 * 20 / C + 29e-9, 1e-12, 8_000))
        self.forward("paper", paper, demo_axis)
        spots32 = np.array([[x, 0.0, z] for x in np.linspace(-2.0, -0.3, 8)
                            for z in np.linspace(-0.6, 0.6, 4)])
        detailed = Scene(paper_setup(detector_spots=spots32),
                         Target(box((0.5, 0.5, 1.7), (3.0, 2.5, 0.0), 0.0125 if s else 0.1)),
                         0.0125 if s else 0.1)
        self.forward("detailed mesh", detailed, TimeAxis(2 * 20 / C + 6e-9, 10e-12,
                                                         4096 if s else 2048))
        self.say("gauss_filter")
        rng = np.random.default_rng(0)
        self.gauss_filter("paper", rng.standard_normal((3, 60_000 if s else 6_000)), 1e-12)
        self.gauss_filter("SPAD array", rng.standard_normal((1024 if s else 64, 4096)), 10e-12)
        self.say("ellipse_score")
        signal3 = self._smooth_signals(3)
        paper_spots = paper_setup().detector_spots
        for n in ((601, 2048) if s else (64,)):
            self.ellipse_score("plane", signal3, paper_spots,
                               Grid((0.0, 0.01, 0.0), (6 / (n - 1), 6 / n, 0.01), (n, n, 1)))
        spad = np.array([[x, 0.0, z] for x in np.linspace(-1.6, -0.4, 32)
                         for z in np.linspace(-0.6, 0.6, 32)])
        n_spad = 1024 if s else 64
        self.ellipse_score("SPAD 32x32", self._smooth_signals(n_spad), spad[:n_spad],
                           Grid((2.0, 0.5, 0.0), (4 / 512, 4 / 512, 0.01), (512, 512, 1)
                                if s else (64, 64, 1)), log_mode=True,
                           twin_detectors=64 if s else None)
        m = 256 if s else 32
        self.ellipse_score("volume", signal3, paper_spots,
                           Grid((2.0, 0.5, -1.0), (4 / m, 4 / m, 2 / m), (m, m, m)))
        self.say("pipeline")
        self.pipeline("demo", paper, demo_axis, Grid() if s else Grid.from_ranges(x=(3, 5), y=(1, 3), step_m=0.05))
        n = 512 if s else 64
        self.stream("tracking", 1000 if s else 20,
                    Grid((2.0, 0.5, 0.0), (4 / n, 4 / n, 0.01), (n, n, 1)),
                    twin_frames=10 if s else 2)
        return self.rows

    @staticmethod
    def _smooth_signals(n_det, n_bins=4096):
        """Filtered-looking rows (a broad pulse per row) on a 10 ps axis from path 7 m."""
        k = np.arange(n_bins)
        centres = 1500 + 40 * np.arange(n_det) % 1500
        return np.exp(-0.5 * ((k[None, :] - centres[:, None]) / 60.0) ** 2)

    # --------------------------------------------------------------- reports
    def report(self, out_dir: Path | None):
        lim = self.limits
        head = (f"Device: {self.rt.name}\n\n"
                f"Measured limits: exp {lim['exp_per_s'] / 1e9:.2f} G lanes/s (float8), "
                f"FMA {lim['fma_per_s'] / 1e9:.1f} G/s, copy {lim['bytes_per_s'] / 1e9:.1f} GB/s "
                "(read + write)\n")
        lines = ["| case | size | kernel (ms) | twin (ms) | ratio | build (s) | throughput | "
                 "fraction of limit | bound | peak host MiB | note |",
                 "|---|---|---:|---:|---:|---:|---:|---:|---|---:|---|"]
        for r in self.rows:
            frac = "-" if math.isnan(r.fraction) else f"{100 * r.fraction:.0f} %"
            lines.append(f"| {r.case} | {r.size} | {r.kernel_s * 1e3:.2f} | {r.twin_s * 1e3:.1f} | "
                         f"{r.ratio:.1f}x | {r.build_s:.2f} | {r.throughput:.3g} {r.unit} | {frac} | "
                         f"{r.bound} | {r.peak_host_mb:.0f} | {r.note} |")
        table = "\n".join(lines)
        text = head + "\n" + table + "\n"
        if out_dir is not None:
            (out_dir / "performance.md").parent.mkdir(parents=True, exist_ok=True)
            (out_dir / "performance.md").write_text(
                "# Performance\n\nGenerated by `nlos-cl bench --out docs` (do not edit by hand). "
                "Kernel: median of 5 runs after a warm-up; build: first call minus that median; "
                "ratio: twin time / kernel time; fraction of limit: achieved throughput over the "
                "probe-measured limit named in *bound*.\n\n" + text
                + "\n![time against problem size](performance.png)\n\n" + ANALYSIS)
            out_dir.mkdir(parents=True, exist_ok=True)
            (out_dir / "performance.json").write_text(json.dumps(
                {"device": self.rt.name, "limits": lim, "smoke": self.smoke,
                 "rows": [asdict(r) | {"ratio": r.ratio} for r in self.rows]}, indent=1))
            self._plot(out_dir / "performance.png")
        return text

    def _plot(self, path):
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(1, 3, figsize=(14, 4.2), layout="constrained")
        for ax, case, xlabel in zip(axes, ("forward", "gauss_filter", "ellipse_score"),
                                    ("facets x detectors x bins", "bins x taps",
                                     "cells x detectors")):
            rows = sorted((r for r in self.rows if r.case == case), key=lambda r: r.work)
            x = [r.work for r in rows]
            ax.loglog(x, [r.kernel_s for r in rows], "o-", label="OpenCL kernel")
            ax.loglog(x, [r.twin_s for r in rows], "s--", label="NumPy twin")
            ax.set_xlabel(xlabel)
            ax.set_ylabel("time (s)")
            ax.set_title(case)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend()
        fig.savefig(path, dpi=100)
        plt.close(fig)
