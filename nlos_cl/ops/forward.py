"""forward (kernels/forward.cl): the photon-flight model, paper Eq. 19-21.

Per (facet, detector): hidden path s = r1 + r2 and geometric weight
g = cos_a1 cos_b1 cos_a2 cos_b2 area / (r1^2 r2^2) x the reflectance's direction factor, 0 where
the facet faces away from the laser spot O or the detector spot; then every bin receives
g (erf(z_hi) - erf(z_lo)), z = (bin edge - s) / (sqrt(2) sigma): twice the pulse energy fraction
inside the bin. The host applies the physical constants in float64.

Signature (both backends): forward(facets, spots, laser, edge0, dpath, sigma_path, n_bins,
reflectance=None) -> (histograms (D, n_bins), path span (D, 2): min and max contributing path).
"""
from __future__ import annotations

import math

import numpy as np

from .base import Example, Operation, relative_error

REACH_SIGMAS = 6.0  # a facet's pulse is cut off 6 sigma from its centre: 2e-9 of its energy
FACET_CHUNK = 64  # facets per culling chunk in the kernel
BLOCK = 15  # bins per work item in pulse_bins (BLOCK in forward.cl)
_PAIRS_PER_BLOCK = 1 << 22  # the twin works on blocks of this many (facet, bin) pairs


# ---------------------------------------------------------------------------- twin

def facet_paths(centres, normals, areas, spots, laser, reflectance=None):
    """Hidden path r1 + r2 and geometric weight per (detector, facet), float64."""
    v1 = centres - laser  # (F, 3) O -> facet
    r1 = np.linalg.norm(v1, axis=1)
    v2 = spots[:, None, :] - centres[None, :, :]  # (D, F, 3) facet -> spot
    r2 = np.linalg.norm(v2, axis=2)
    cos_b1 = -np.einsum("fk,fk->f", normals, v1) / r1
    cos_a2 = np.einsum("fk,dfk->df", normals, v2) / r2
    cos_a1 = np.abs(v1[:, 1]) / r1  # the wall's normal is +y
    cos_b2 = np.abs(v2[:, :, 1]) / r2
    lit = (cos_b1 > 0)[None, :] & (cos_a2 > 0)
    weight = cos_a1 * cos_b1 * cos_a2 * cos_b2 * areas / (r1 ** 2 * r2 ** 2)
    if reflectance is not None:
        weight = weight * reflectance.factor(normals, -v1 / r1[:, None], v2 / r2[..., None])
    return r1[None, :] + r2, np.where(lit, weight, 0.0)


def pulse_bins(path, weight, edge0, dpath, sigma_path, n_bins):
    """hist[d, k] = sum_f w[d, f] (erf(z_{k+1}) - erf(z_k)); each facet touches only the bins
    within REACH_SIGMAS of its path (work = facets x a fixed window, via np.bincount)."""
    from scipy.special import erf
    hist = np.zeros((path.shape[0], n_bins))
    reach = REACH_SIGMAS * sigma_path
    inv = 1.0 / (math.sqrt(2.0) * sigma_path)
    for d in range(path.shape[0]):
        lit = weight[d] > 0
        s, w = path[d, lit], weight[d, lit]
        window = int(math.ceil(2 * reach / dpath[d])) + 2
        first = np.floor((s - reach - edge0[d]) / dpath[d]).astype(np.int64)
        block = max(1, _PAIRS_PER_BLOCK // window)
        for lo in range(0, s.size, block):  # bounds memory, not a per-facet loop
            sl = slice(lo, lo + block)
            bins = first[sl, None] + np.arange(window)
            low_edge = edge0[d] + bins * dpath[d] - s[sl, None]
            e = erf(np.concatenate([low_edge, low_edge[:, -1:] + dpath[d]], axis=1) * inv)
            contrib = w[sl, None] * np.diff(e, axis=1)
            ok = (bins >= 0) & (bins < n_bins)
            hist[d] += np.bincount(bins[ok], contrib[ok], minlength=n_bins)
    return hist


def path_range(path, weight):
    """(D, 2) min and max hidden path over the facets that contribute (inf, -inf if none)."""
    lit = weight > 0
    return np.stack([np.where(lit, path, np.inf).min(axis=1),
                     np.where(lit, path, -np.inf).max(axis=1)], axis=1)


def numpy(facets, spots, laser, edge0, dpath, sigma_path, n_bins, reflectance=None):
    path, weight = facet_paths(facets.centres, facets.normals, facets.areas,
                               np.asarray(spots, np.float64), np.asarray(laser, np.float64),
                               reflectance)
    return pulse_bins(path, weight, edge0, dpath, sigma_path, n_bins), path_range(path, weight)


# ---------------------------------------------------------------------------- OpenCL

def opencl(rt, facets, spots, laser, edge0, dpath, sigma_path, n_bins, reflectance=None,
           out=None):
    from ..runtime import float4, float4_rows
    n_det, n_facets = len(spots), facets.count
    n_chunks = -(-n_facets // FACET_CHUNK)
    n_pad = n_chunks * FACET_CHUNK
    centres, normals = float4_rows(facets.centres), float4_rows(facets.normals)
    normals[:, 3] = facets.areas
    centres, normals = rt.from_numpy(centres), rt.from_numpy(normals)
    spots_buf = rt.constant(float4_rows(spots))
    axis = rt.constant(np.stack([edge0, dpath], axis=1))
    defines = dict(CHUNK=FACET_CHUNK, **(reflectance.kernel_defines() if reflectance else {}))
    paths_kernel = rt.kernel("forward", "facet_paths", **defines)
    bins_kernel = rt.kernel("forward", "pulse_bins", **defines)
    hist = out if out is not None else rt.empty((n_det, n_bins))
    spans = []
    for d0, d1 in rt.groups(n_det, 4 * n_pad, "facet paths of one detector"):
        path, weight = rt.empty((d1 - d0, n_pad)), rt.empty((d1 - d0, n_pad))
        ranges = rt.empty((d1 - d0, n_chunks, 2))
        rt.run(paths_kernel, (n_chunks, d1 - d0), centres, normals, np.int32(n_facets),
               spots_buf, float4(laser), np.int32(d0), path, weight, ranges)
        rt.run(bins_kernel, (-(-n_bins // BLOCK), d1 - d0), path, weight, ranges,
               np.int32(n_chunks), axis, np.float32(1.0 / (math.sqrt(2.0) * sigma_path)),
               np.float32(REACH_SIGMAS * sigma_path), np.int32(n_bins), np.int32(d0), hist)
        r = rt.to_numpy(ranges)  # tiny (D, chunks, 2): for the caller's window check
        spans.append(np.stack([r[..., 0].min(axis=1), r[..., 1].max(axis=1)], axis=1))
    return hist, np.concatenate(spans)


# ---------------------------------------------------------------------------- examples

def scene_inputs(scene, time_axis):
    """forward's arguments for a scene on a time axis (as nlos_cl.simulate passes them)."""
    from ..constants import SPEED_OF_LIGHT
    from ..paths import PathAxis, PathCalibration
    setup = scene.setup
    paths = PathAxis.of(time_axis, PathCalibration.for_setup(setup), setup.n_detectors)
    return (scene.facets(), setup.detector_spots, setup.laser_spot, paths.start_m, paths.step_m,
            SPEED_OF_LIGHT * setup.pulse.sigma_s, time_axis.n_bins, scene.target.reflectance)


def _window(scene, dt_s, margin_m=0.1):
    """A short time axis over every hidden path the facets produce, plus a margin."""
    from ..constants import SPEED_OF_LIGHT as C
    from ..paths import TimeAxis
    setup, facets = scene.setup, scene.facets()
    paths = np.linalg.norm(facets.centres - setup.laser_spot, axis=1)[None] + np.linalg.norm(
        facets.centres[None] - setup.detector_spots[:, None], axis=2)
    t0 = (2 * setup.device_distance_m + paths.min() - margin_m) / C + setup.pulse.peak_delay_s
    return TimeAxis(t0, dt_s, int(math.ceil((np.ptp(paths) + 2 * margin_m) / (C * dt_s))))


def erf_lanes(facets, spots, laser, edge0, dpath, sigma_path, n_bins, reflectance=None):
    """erf lanes pulse_bins evaluates: 16 per (15-bin block, facet within reach)."""
    path, weight = facet_paths(facets.centres, facets.normals, facets.areas, spots, laser)
    reach, total = REACH_SIGMAS * sigma_path, 0
    starts = np.arange(0, n_bins, BLOCK)
    for d in range(len(path)):
        s = np.sort(path[d][weight[d] > 0])
        base = edge0[d] + dpath[d] * starts
        lo = np.searchsorted(s, base - reach)
        hi = np.searchsorted(s, base + dpath[d] * BLOCK + reach, side="right")
        total += int((hi - lo).sum())
    return 16.0 * total


def _span_error(device, twin) -> float:
    """Largest difference (m) between the contributing path spans."""
    return float(np.abs(device[1] - twin[1]).max())


def _bench_examples(hist_err):
    from ..constants import SPEED_OF_LIGHT as C
    from ..meshes import box
    from ..paths import TimeAxis, default_time_axis
    from ..scene import Scene, Target, paper_scene, paper_setup
    paper = paper_scene(facet_size_m=0.01)
    spots32 = [[x, 0.0, z] for x in np.linspace(-2.0, -0.3, 8) for z in np.linspace(-0.6, 0.6, 4)]
    detailed = Scene(paper_setup(detector_spots=spots32),
                     Target(box((0.5, 0.5, 1.7), (3.0, 2.5, 0.0), 0.0125)), 0.0125)
    out = []
    for label, scene, axis in (("paper", paper, default_time_axis(paper.setup)),
                               ("detailed mesh", detailed, TimeAxis(40 / C + 6e-9, 10e-12, 4096))):
        args = scene_inputs(scene, axis)
        out.append(Example(f"{label}: {args[0].count} facets x {len(args[1])} det x "
                           f"{axis.n_bins} bins", (lambda a: lambda be: a)(args), 1e-3,
                           hist_err, work=erf_lanes(*args), unit="erf lanes"))
    return out


def examples(size):
    from ..scene import paper_scene
    hist_err = lambda a, b: relative_error(a[0], b[0])  # noqa: E731
    if size == "bench":
        return _bench_examples(hist_err)
    scene = paper_scene(facet_size_m=0.07 if size == "tiny" else 0.02)  # tiny: a partial chunk
    args = scene_inputs(scene, _window(scene, 10e-12))
    n_pad = -(-args[0].count // FACET_CHUNK) * FACET_CHUNK
    inputs = lambda be: args  # noqa: E731
    return [Example("paper rectangle: histograms", inputs, 1e-3, hist_err),
            Example("paper rectangle: contributing path span (m)", inputs, 1e-5, _span_error),
            Example("one detector per group", inputs, 1e-3, hist_err, max_alloc_bytes=4 * n_pad)]


OP = Operation(
    "forward", "forward", opencl, numpy, examples,
    tolerance_note="histograms 1e-3 of the peak: paths of ~10 m round to ~1e-6 m in float32, "
    "1e-4 of the pulse sigma; bin widths are exact (edges from one base); erf errs ~1e-6 "
    "against a bin's erf difference of ~0.03. Path span 1e-5 m: float32 paths of ~10 m.",
    bound="exp (erf = ~2 exp per lane)")
