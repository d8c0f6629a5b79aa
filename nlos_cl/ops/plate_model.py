"""plate_model (kernels/plate_model.cl): the model fit's plates evaluated on the device, many per
call: the host model of nlos_cl/localization/model/forward/batch.py (HostProblem(kernel=True) calls
this; tests/ops/test_plate_model.py holds the two together), its float64 twin here written out
plate by plate.

plate_model(rows (B, 6), stat_rows (R, 6), stat_of (B,), spots (D, 3), laser ((3,): one for
every spot; (D, 3): each spot's, a confocal scan or a paired layout), some (S,) (the statistics
spots' indices into spots), affine (D, S), edge0 (D,), dpath (D,), sigma0sq, n_bins, os_,
lattice, blur_share, gauss_2) -> (B, D, n_bins) unit-amplitude histograms: plate b with the
cell statistics (pull-in, blur, shift at the S statistics spots, carried to the D spots by
`affine`) of stat_rows[stat_of[b]] (its own, or a Jacobian's unmoved plate's), the pulse's sigma^2 = sigma0sq + blur^2 (sigma0sq: the
observation's sigma0^2 less its box excess), bins of dpath[d] metres of path from edge0[d],
os_ sub-bins a bin; blur_share and gauss_2: the plate model's constants (model.plate). No
mask: the caller zeroes the bins outside the record.

Why: a warm tracker frame is ~9 host-model calls (residuals of one plate, Jacobians of five),
each ~100 NumPy passes over ~5,000 values: 0.8-1.1 ms whatever the arithmetic. Here a call is
one upload, two launches and one read (`Plan`); measured, that costs about as much as the
host's NumPy on PoCL and on an H200 (nlos_cl/apps/bench/analysis.md).

The window's pad (bins each side) is taken from an upper bound of the pulse's width (the
blur^2 is at most BLUR_SHARE x (2 |Gauss offset|)^2: a point's path moves by at most twice its
offset from the cell centre), where the twin takes the batch's widest actual pulse; the two
differ only in what lies beyond REACH_SIGMAS (2e-9 of a pulse's energy).
"""
from __future__ import annotations

import math

import numpy as np

from ..core.constants import TINY
from .base import Example, Operation
from .pulse import REACH_SIGMAS

WORK_GROUP = 64  # work items per plate (stats) and per (plate, detector) (histograms)
SIGMA0 = 0.0655  # the examples' pulse (m of path): the paper's 70 ps pulse after its Gauss filter
WIDTH, HEIGHT, YAW = 3, 4, 5  # a row's (x, y, z, width, height, yaw): localization.model.shapes.plate


def local_bytes(cells: int) -> int:
    """The local memory plate_hist needs: each point's weight and place (2 floats x 4 points a
    cell) and WORK_GROUP floats."""
    return 32 * cells + 4 * WORK_GROUP


MAX_CELLS = (32768 - local_bytes(0)) // 32  # 1,016: what the 32 KiB of every device holds


def pad_bound(rows, lattice, sigma0sq, dpath, blur_share, gauss_2) -> int:
    """Bins each side of the window: REACH_SIGMAS of the widest pulse any of `rows` can have."""
    nu, nv = lattice
    rows = np.atleast_2d(rows)
    offset2 = gauss_2 ** 2 * ((rows[:, WIDTH] / nu) ** 2 + (rows[:, HEIGHT] / nv) ** 2)
    sigma = math.sqrt(max(sigma0sq + blur_share * 4.0 * float(np.max(offset2)), TINY))
    return int(math.ceil(REACH_SIGMAS * sigma / float(np.min(dpath)))) + 1


def _points(row, lattice, gauss_2):
    """A plate's cell centres (C, 3), its Gauss points' offsets from them (4, C, 3), its
    normal and the area each point stands for (plate.plate_facets' cell order)."""
    nu, nv = lattice
    x, w, h, yaw = row[:3], row[WIDTH], row[HEIGHT], row[YAW]
    normal = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    across = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    u = ((np.arange(nu) + 0.5) / nu - 0.5) * w
    v = ((np.arange(nv) + 0.5) / nv - 0.5) * h
    centres = (x + u[:, None, None] * across + v[None, :, None] * up).reshape(-1, 3)
    eu, ev = across * w / nu, up * h / nv
    offsets = np.array([gauss_2 * (su * eu + sv * ev) for su in (-1, 1) for sv in (-1, 1)])
    return centres, np.broadcast_to(offsets[:, None], (4, len(centres), 3)), normal, \
        w * h / (nu * nv) / 4.0


def _legs(points, normal, area, centre, spot, laser):
    """Path r1 + r2 and weight cos a1 cos b1 cos a2 cos b2 area / (r1^2 r2^2) (the relay wall
    is y = 0; a plate facing away from the laser spot or the wall spot sends nothing)."""
    v1, v2 = points - laser, spot - points
    r1, r2 = np.linalg.norm(v1, axis=-1), np.linalg.norm(v2, axis=-1)
    cos_b1 = max(float(normal @ (laser - centre)), 0.0) / r1
    cos_a2 = max(float(normal @ (spot - centre)), 0.0) / r2
    return r1 + r2, np.abs(v1[..., 1]) / r1 * cos_b1 * np.abs(v2[..., 1]) / r2 * cos_a2 * area \
        / (r1 * r1 * r2 * r2)


def _statistics(row, lattice, stat_spots, stat_lasers, blur_share, gauss_2):
    """(keep (C,), blur^2, shift (S,)): each cell's pull-in, the shared blur and the shift at
    each statistics spot (plate.cell_model's rule, written out plate by plate)."""
    centres, offsets, normal, area = _points(row, lattice, gauss_2)
    mean, var, wsum = [], [], []
    for spot, laser in zip(stat_spots, stat_lasers):
        path, weight = _legs(centres + offsets, normal, area, row[:3], spot, laser)
        centre_path = np.linalg.norm(centres - laser, axis=1) + \
            np.linalg.norm(spot - centres, axis=1)
        total = weight.sum(axis=0)
        m = (weight * path).sum(axis=0) / np.maximum(total, TINY)
        var.append((weight * (path - m) ** 2).sum(axis=0) / np.maximum(total, TINY))
        mean.append(m - centre_path)
        wsum.append(total)
    mean, var, wsum = np.array(mean), np.array(var), np.array(wsum)  # (S, C)
    var_c = (var * wsum).sum(axis=0) / np.maximum(wsum.sum(axis=0), TINY)
    lit = wsum.sum(axis=0) > 0
    blur2 = blur_share * float(var_c[lit].mean()) if lit.any() else 0.0
    keep = np.sqrt(np.clip(1.0 - blur2 / np.maximum(var_c, TINY), 0.0, 1.0))
    shift = ((1.0 - keep ** 2) * mean * wsum).sum(axis=1) / np.maximum(wsum.sum(axis=1), TINY)
    return keep, blur2, shift


def lasers_of(spots, laser) -> np.ndarray:
    """(D, 3): each spot's laser spot (one laser spot (3,) replicated)."""
    laser = np.asarray(laser, np.float64)
    return np.broadcast_to(laser, np.shape(spots)).copy() if laser.ndim == 1 else laser


def numpy(rows, stat_rows, stat_of, spots, laser, some, affine, edge0, dpath, sigma0sq, n_bins,
          os_, lattice, blur_share, gauss_2):
    """The twin, written plate by plate and detector by detector: each point's pulse integrated
    over each bin exactly (erf differences), where the kernel (and the host model,
    localization/model/forward/batch.py) split it between two sub-bins first (the tolerance below)."""
    from ..core.erf import erf
    rows, stat_rows = (np.atleast_2d(np.asarray(r, np.float64)) for r in (rows, stat_rows))
    spots = np.asarray(spots, np.float64)
    lasers, some = lasers_of(spots, laser), np.asarray(some, int)
    stats = [_statistics(r, lattice, spots[some], lasers[some], blur_share, gauss_2)
             for r in stat_rows]
    out = np.zeros((len(rows), len(spots), int(n_bins)))
    for b, row in enumerate(rows):
        keep, blur2, shift = stats[int(np.asarray(stat_of)[b])]
        centres, offsets, normal, area = _points(row, lattice, gauss_2)
        points = (centres + keep[:, None] * offsets).reshape(-1, 3)
        scale = 1.0 / math.sqrt(2.0 * (sigma0sq + blur2))
        for d, (spot, laser) in enumerate(zip(spots, lasers)):
            path, weight = _legs(points, normal, area, row[:3], spot, laser)
            edges = edge0[d] - float(np.asarray(affine)[d] @ shift) + dpath[d] * np.arange(
                int(n_bins) + 1)
            e = erf((edges[None, :] - path[:, None]) * scale)
            out[b, d] = weight @ (e[:, 1:] - e[:, :-1])
    return out


class Plan:
    """The operation for one observation's geometry (spots, statistics spots, affine, laser,
    bin widths, lattice, sub-bins): its kernels fetched, its constants uploaded and its
    scratch buffers kept (grown when a call needs more), so that a call is one upload, two
    launches and one read. pyopencl Arrays, a kernel look-up and a constant's hash each cost
    tens of microseconds, ~0.5 ms a call when made afresh (measured on PoCL), as much as the
    launches: a fit's ~10 calls a frame (HostProblem(kernel=True)) keep one Plan."""

    def __init__(self, rt, spots, laser, some, affine, dpath, os_, lattice, blur_share, gauss_2):
        import pyopencl as cl

        from ..device.runtime import float4_rows
        self.rt, self.cl = rt, cl
        self.spots = np.asarray(spots, np.float64)
        self.lasers, some = lasers_of(self.spots, laser), np.asarray(some, int)
        self.dpath, self.os = np.asarray(dpath, np.float64), int(os_)
        self.lattice = tuple(int(v) for v in lattice)
        self.blur_share, self.gauss_2 = float(blur_share), float(gauss_2)
        self.n_det, self.n_stat = len(self.spots), len(some)
        need = local_bytes(self.lattice[0] * self.lattice[1])
        if need > rt.device.local_mem_size:
            raise ValueError(f"plate_model: a lattice of {self.lattice} cells needs {need} bytes "
                             f"of local memory, more than {rt.device.local_mem_size} on "
                             f"{rt.name}; pass a coarser lattice (<= {MAX_CELLS} cells)")
        defines = dict(NU=self.lattice[0], NV=self.lattice[1], OS=self.os, WG=WORK_GROUP,
                       BLUR_SHARE=f"{self.blur_share!r}f", GAUSS_2=f"{self.gauss_2!r}f")
        self.stats_kernel = rt.kernel("plate_model", "plate_stats", **defines)
        self.hist_kernel = rt.kernel("plate_model", "plate_hist", **defines)
        self.constants = [rt.constant(float4_rows(self.spots[some])),
                          rt.constant(float4_rows(self.lasers[some])), rt.constant(affine),
                          rt.constant(float4_rows(self.spots)),
                          rt.constant(float4_rows(self.lasers)), rt.constant(self.os / self.dpath)]
        self.buffers: dict = {}

    def _buffer(self, name, nbytes):
        """A kept device buffer of at least nbytes (grown by doubling)."""
        got = self.buffers.get(name)
        if got is None or got.size < nbytes:
            size = max(nbytes, 2 * (got.size if got is not None else 0), 64)
            got = self.buffers[name] = self.cl.Buffer(self.rt.context, self.cl.mem_flags.READ_WRITE,
                                                      size)
        return got

    def __call__(self, rows, stat_rows, stat_of, edge0, sigma0sq, n_bins) -> np.ndarray:
        """(B, D, n_bins) float32 histograms (the operation's, for these rows)."""
        cl, rt = self.cl, self.rt
        rows, stat_rows = (np.atleast_2d(np.asarray(r, np.float64)) for r in (rows, stat_rows))
        n_b, n_r, n_det, n_bins = len(rows), len(stat_rows), self.n_det, int(n_bins)
        nu, nv = self.lattice
        pad = pad_bound(np.vstack([rows, stat_rows]), self.lattice, sigma0sq, self.dpath,
                        self.blur_share, self.gauss_2)
        # the centre's path relative to the window's first sub-bin edge, in float64 here: the
        # kernel adds only each point's (small) path difference from the centre
        centre = rows[:, None, :3]
        centre_path = (np.sqrt(((centre - self.lasers[None]) ** 2).sum(axis=-1))
                       + np.sqrt(((self.spots[None] - centre) ** 2).sum(axis=-1))
                       - (np.asarray(edge0, np.float64) - pad * self.dpath)[None])
        # one upload: the statistics rows and the rows (float8 each), the centres' paths and
        # each row's statistics row (exact in float32: far fewer than 2^24 rows)
        packed = np.zeros(8 * (n_r + n_b) + n_b * n_det + n_b, np.float32)
        packed[:8 * n_r].reshape(n_r, 8)[:, :6] = stat_rows
        packed[8 * n_r:8 * (n_r + n_b)].reshape(n_b, 8)[:, :6] = rows
        packed[8 * (n_r + n_b):-n_b] = centre_path.ravel()
        packed[-n_b:] = np.asarray(stat_of).ravel()
        per_call = self._buffer("per_call", packed.nbytes)
        cl.enqueue_copy(rt.queue, per_call, packed, is_blocking=False)
        keep = self._buffer("keep", 4 * n_r * nu * nv)
        stats = self._buffer("stats", 4 * n_r * (1 + self.n_stat))
        n_sub = (n_bins + 2 * pad) * self.os
        dep = self._buffer("dep", 4 * n_b * n_det * n_sub)
        taps = self._buffer("taps", 4 * n_b * n_det * self.os * (2 * pad + 1))
        hist = self._buffer("hist", 4 * n_b * n_det * n_bins)
        spots_stat, lasers_stat, affine, spots4, lasers4, inv_dsub = (
            c.data for c in self.constants)
        self.stats_kernel.set_args(per_call, spots_stat, lasers_stat, np.int32(self.n_stat),
                                   keep, stats)
        cl.enqueue_nd_range_kernel(rt.queue, self.stats_kernel, (n_r * WORK_GROUP,),
                                   (WORK_GROUP,))
        self.hist_kernel.set_args(
            per_call, np.int32(n_r), np.int32(8 * (n_r + n_b)),
            np.int32(8 * (n_r + n_b) + n_b * n_det), keep, stats, affine, np.int32(self.n_stat),
            spots4, lasers4, inv_dsub, np.float32(sigma0sq), np.int32(n_bins),
            np.int32(pad), dep, taps, hist)
        cl.enqueue_nd_range_kernel(rt.queue, self.hist_kernel, (n_b * WORK_GROUP, n_det),
                                   (WORK_GROUP, 1))
        out = np.empty((n_b, n_det, n_bins), np.float32)
        cl.enqueue_copy(rt.queue, out, hist, is_blocking=True)  # (after the upload: in order)
        rt.launched.update({("plate_model", "plate_stats"), ("plate_model", "plate_hist")})
        return out


def opencl(rt, rows, stat_rows, stat_of, spots, laser, some, affine, edge0, dpath, sigma0sq,
           n_bins, os_, lattice, blur_share, gauss_2, out=None):
    """The operation through a Plan made for this call (HostProblem keeps one instead)."""
    plan = Plan(rt, spots, laser, some, affine, dpath, os_, lattice, blur_share, gauss_2)
    return plan(rows, stat_rows, stat_of, edge0, sigma0sq, n_bins)


def _scene(n_plates, n_det, n_stat, lattice, n_bins, os_, seed=0, away=False, confocal=False):
    """The paper's geometry (a laser spot and wall spots on y = 0, plates ~2-3 m out) with
    plates near one another, as a Jacobian's: the first carries the statistics of the rest.
    confocal: each spot its own laser spot (a confocal scan)."""
    rng = np.random.default_rng(seed)
    base = np.array([2.0, 2.8, 0.1, 0.3, 1.6, -math.pi / 2 + 0.3])  # facing the wall
    rows = base + np.vstack([np.zeros(6), rng.normal(0, [0.002, 0.002, 0.002, 0.002, 0.002,
                                                         0.004], (n_plates - 1, 6))])
    if away:
        rows[1, 5] += math.pi
    laser = np.array([-0.5, 0.0, 0.0])
    spots = np.column_stack([np.linspace(-1.2, -0.4, n_det), np.zeros(n_det),
                             np.linspace(-0.3, 0.3, n_det)])
    if confocal:
        laser = spots.copy()
    some = np.unique(np.linspace(0, n_det - 1, n_stat).round().astype(int))
    if len(some) < n_det:  # HostProblem's affine spread of the shift
        basis = np.hstack([np.ones((n_det, 1)), spots - spots.mean(axis=0)]
                          + ([laser - laser.mean(axis=0)] if confocal else []))
        affine = basis @ np.linalg.pinv(basis[some])
    else:
        affine = np.eye(n_det)
    dpath = np.full(n_det, 0.021)
    near = np.linalg.norm(rows[0, :3] - laser, axis=-1) + np.linalg.norm(spots - rows[0, :3],
                                                                        axis=1)
    edge0 = near - 0.5 * n_bins * 0.021  # the plate's returns mid-window
    stat_of = np.zeros(n_plates, int) if not away else np.arange(n_plates)
    return (rows, rows[:1] if not away else rows, stat_of, spots, laser, some, affine, edge0,
            dpath, SIGMA0 ** 2, n_bins, os_, lattice, 0.5, 0.5 / math.sqrt(3.0))


def _inputs(*scene_args, **kw):
    args = _scene(*scene_args, **kw)
    return lambda be: args


def _tolerance(dpath, os_):
    """The linear split's bound, (dsub / sigma)^2 / 8 of the peak (the twin integrates each
    point's pulse exactly; the kernel splits it between two sub-bins of dsub first), plus 2e-5
    for float32 (path differences, the 2^30 fixed-point deposit, A&S erf taps: ~1e-6 measured
    against the host model, tests/ops/test_plate_model.py)."""
    return (dpath / os_ / SIGMA0) ** 2 / 8.0 + 2e-5


def examples(size):
    if size == "tiny":  # a 2 x 3 lattice, a short window, 4 sub-bins (not the 8-wide path),
        # and a plate turned away from the wall (no weight: the deposit's zero-sum branch)
        return [Example("2 plates x 3 confocal spots x 24 bins, lattice 2 x 3",
                        _inputs(2, 3, 2, (2, 3), 24, 4, confocal=True), _tolerance(0.021, 4)),
                Example("2 plates x 2 det x 24 bins, lattice 2 x 3",
                        _inputs(2, 2, 2, (2, 3), 24, 4), _tolerance(0.021, 4)),
                Example("a plate facing away beside one facing the wall",
                        _inputs(2, 2, 2, (2, 3), 24, 4, away=True), _tolerance(0.021, 4))]
    return [Example("a Jacobian: 6 plates x 3 det x 80 bins, lattice 16 x 24, 8 sub-bins",
                    _inputs(6, 3, 3, (16, 24), 80, 8), _tolerance(0.021, 8), work=6 * 3 * 1536,
                    unit="point-detectors"),
            Example("6 plates x 40 det (32 statistics spots, affine) x 80 bins",
                    _inputs(6, 40, 32, (16, 24), 80, 8), _tolerance(0.021, 8),
                    work=6 * 40 * 1536, unit="point-detectors"),
            Example("a confocal scan: 6 plates x 40 spots, each its own laser spot",
                    _inputs(6, 40, 32, (16, 24), 80, 8, confocal=True), _tolerance(0.021, 8),
                    work=6 * 40 * 1536, unit="point-detectors")]


OP = Operation(
    "plate_model", "plate_model", opencl, numpy, examples,
    tolerance_note="the linear split's (dsub / sigma)^2 / 8 of the peak (the twin integrates "
    "each point's pulse exactly) plus 2e-5 for float32: path differences from the plate's "
    "centre (its path in float64 on the host), a 2^30 fixed-point deposit, A&S erf taps. "
    "Against the host model (the same split): ~1e-6, tests/ops/test_plate_model.py.",
    bound="launches and one read per call (a few thousand points)")
