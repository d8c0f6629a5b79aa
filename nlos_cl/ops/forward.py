"""forward (kernels/forward.cl): the photon-flight model, paper Eq. 19-21.

Per (facet, detector): hidden path s = r1 + r2 and geometric weight
g = cos_a1 cos_b1 cos_a2 cos_b2 area / (r1^2 r2^2) x the reflectance's direction factor, 0 where
the facet faces away from the laser spot O or the detector spot; then every bin receives
g (erf(z_hi) - erf(z_lo)), z = (bin edge - s) / (sqrt(2) sigma): twice the pulse energy fraction
inside the bin. The host applies the physical constants in float64.

Signature (both backends): forward(facets, spots, laser, edge0, dpath, sigma_path, n_bins,
reflectance=None, method=..., visible=None) -> (histograms (D, n_bins), path span (D, 2): min
and max contributing path). `visible` (D, F) bool: occlusion, a facet sends nothing to a
detector where it does not see the laser spot or that detector's spot. laser: (3,), every
detector's laser spot O, or (D, 3), each detector's own (paired and confocal layouts: the
kernel's -D PAIRED=1 reads lasers[d]).
"""
from __future__ import annotations

import math

import numpy as np

from ..core.histograms import laser_spots_of
from .base import Example, Operation, relative_error
from .ellipse_score import paired

from .pulse import (REACH_SIGMAS, SUB_BINS_PER_SIGMA, binning, deposit_plan,  # noqa: F401
                    deposit_sizes, deposit_taps, pulse_bins)

from .forward_passes import (BLOCK, FACET_CHUNK, deposit_bins, direct, direct_bins,  # noqa: F401
                             erf_bins, plan_passes)


# ---------------------------------------------------------------------------- twin

def facet_paths(centres, normals, areas, spots, laser, reflectance=None, visible=None):
    """Hidden path r1 + r2 and geometric weight per (detector, facet), float64. laser: (3,),
    whose leg is computed once per facet and shared, or (D, 3), each detector's own."""
    lasers = laser_spots_of(laser, len(spots)) if paired(laser) else np.reshape(laser, (1, 3))
    v1 = centres[None, :, :] - lasers[:, None, :]  # (L, F, 3) O -> facet
    r1 = np.linalg.norm(v1, axis=2)
    v2 = spots[:, None, :] - centres[None, :, :]  # (D, F, 3) facet -> spot
    r2 = np.linalg.norm(v2, axis=2)
    cos_b1 = -np.einsum("fk,lfk->lf", normals, v1) / r1
    cos_a2 = np.einsum("fk,dfk->df", normals, v2) / r2
    cos_a1 = np.abs(v1[:, :, 1]) / r1  # the wall's normal is +y
    cos_b2 = np.abs(v2[:, :, 1]) / r2
    lit = (cos_b1 > 0) & (cos_a2 > 0)
    if visible is not None:  # occlusion: the facet must see the laser and the detector spot
        lit = lit & np.asarray(visible, bool)
    weight = cos_a1 * cos_b1 * cos_a2 * cos_b2 * areas / (r1 ** 2 * r2 ** 2)
    if reflectance is not None:
        weight = weight * _direction_factor(reflectance, normals, -v1 / r1[..., None],
                                            v2 / r2[..., None])
    return r1 + r2, np.where(lit, weight, 0.0)


def _direction_factor(reflectance, normals, to_laser, to_detector):
    """(D, F) reflectance.factor for (L, F, 3) laser directions: one call where L = 1, one per
    detector where each has its own laser spot (factor takes one (F, 3) laser direction)."""
    if len(to_laser) == 1:
        return reflectance.factor(normals, to_laser[0], to_detector)
    return np.concatenate([reflectance.factor(normals, to_laser[d], to_detector[d:d + 1])
                           for d in range(len(to_detector))])


def path_range(path, weight):
    """(D, 2) min and max hidden path over the facets that contribute (inf, -inf if none)."""
    lit = weight > 0
    return np.stack([np.where(lit, path, np.inf).min(axis=1),
                     np.where(lit, path, -np.inf).max(axis=1)], axis=1)


def numpy(facets, spots, laser, edge0, dpath, sigma_path, n_bins, reflectance=None,
          method=None, visible=None):
    """The exact erf path, whatever `method` the device uses."""
    path, weight = facet_paths(facets.centres, facets.normals, facets.areas,
                               np.asarray(spots, np.float64), np.asarray(laser, np.float64),
                               reflectance, visible)
    return pulse_bins(path, weight, edge0, dpath, sigma_path, n_bins), path_range(path, weight)


# ---------------------------------------------------------------------------- OpenCL

def opencl(rt, facets, spots, laser, edge0, dpath, sigma_path, n_bins, reflectance=None,
           method="deposit", visible=None, out=None):
    """method: "deposit" (deposit + convolve, the default; erf where the pulse is too short or
    too long for it: ops/pulse.py) or "erf" (every bin's erf);
    visible: None, or a (detectors, facets) bool mask (occlusion: nlos_cl/visibility.py)."""
    from ..device.runtime import float4, float4_rows
    n_det, n_facets = len(spots), facets.count
    n_chunks = -(-n_facets // FACET_CHUNK)
    n_pad = n_chunks * FACET_CHUNK
    spots_buf = rt.constant(float4_rows(spots))
    is_paired = paired(laser)  # -D PAIRED=1: each detector's laser spot from a buffer
    lasers = rt.constant(float4_rows(laser_spots_of(laser, n_det))) if is_paired else float4(laser)
    hist = out if out is not None else rt.empty((n_det, n_bins))
    method, passes = plan_passes(rt, n_det, n_pad, n_bins, sigma_path, dpath, method)
    if method == "deposit" and direct(rt, n_det, n_bins, sigma_path, dpath, reflectance,
                                      visible):  # its own facet rows: no float4 rows, no mask
        return hist, direct_bins(rt, facets, spots_buf, lasers, is_paired, passes, edge0,
                                 dpath, sigma_path, n_bins, hist)
    centres, normals = float4_rows(facets.centres), float4_rows(facets.normals)
    normals[:, 3] = facets.areas
    centres, normals = rt.from_numpy(centres), rt.from_numpy(normals)
    mask = rt.constant(np.ascontiguousarray(visible if visible is not None else np.ones(1),
                                            np.uint8), np.uint8)
    defines = dict(CHUNK=FACET_CHUNK, **(reflectance.kernel_defines() if reflectance else {}))
    paths_kernel = rt.kernel("forward", "facet_paths", **defines,
                             **(dict(PAIRED=1) if is_paired else {}))
    spans = []
    for d0, d1 in passes:
        path, weight = rt.empty((d1 - d0, n_pad)), rt.empty((d1 - d0, n_pad))
        ranges = rt.empty((d1 - d0, n_chunks, 4))
        rt.run(paths_kernel, (n_chunks, d1 - d0), centres, normals, np.int32(n_facets),
               spots_buf, lasers, np.int32(d0), mask, np.int32(visible is not None),
               path, weight, ranges)
        r = rt.to_numpy(ranges)  # tiny (D, chunks, 4): the window check and the deposit's
        span = np.stack([r[..., 0].min(axis=1), r[..., 1].max(axis=1)], axis=1)
        spans.append(span)
        group = (path, weight, ranges, n_chunks, d0, d1)
        if method == "erf":
            erf_bins(rt, defines, group, edge0, dpath, sigma_path, n_bins, hist)
        else:
            deposit_bins(rt, defines, group, span, r[..., 2].sum(axis=1), edge0, dpath,
                         sigma_path, n_bins, hist)
    return hist, np.concatenate(spans)


# ---------------------------------------------------------------------------- examples

def scene_inputs(scene, time_axis):
    """forward's arguments for a scene on a time axis (as nlos_cl.simulate passes them)."""
    from ..core.constants import SPEED_OF_LIGHT
    from ..core.paths import PathAxis, PathCalibration
    setup = scene.setup
    paths = PathAxis.of(time_axis, PathCalibration.for_setup(setup), setup.n_detectors)
    return (scene.facets(), setup.detector_spots, setup.laser_spot, paths.start_m, paths.step_m,
            SPEED_OF_LIGHT * setup.pulse.sigma_s, time_axis.n_bins, scene.target.reflectance)


def _window(scene, dt_s, margin_m=0.1, laser=None):
    """A short time axis over every hidden path the facets produce, plus a margin; laser: the
    setup's laser spot, or (D, 3) spots (paired)."""
    from ..core.constants import SPEED_OF_LIGHT as C
    from ..core.paths import TimeAxis
    setup, facets = scene.setup, scene.facets()
    lasers = np.reshape(setup.laser_spot if laser is None else laser, (-1, 1, 3))
    paths = np.linalg.norm(facets.centres - lasers, axis=2) + np.linalg.norm(
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
    from ..core.constants import SPEED_OF_LIGHT as C
    from ..core.paths import TimeAxis, default_time_axis
    from ..physics.meshes import box
    from ..physics.scene import Scene, Target, paper_scene, paper_setup
    paper = paper_scene(facet_size_m=0.01)
    spots32 = [[x, 0.0, z] for x in np.linspace(-2.0, -0.3, 8) for z in np.linspace(-0.6, 0.6, 4)]
    detailed = Scene(paper_setup(detector_spots=spots32),
                     Target(box((0.5, 0.5, 1.7), (3.0, 2.5, 0.0), 0.0125)), 0.0125)
    out = []
    for label, scene, axis in (("paper", paper, default_time_axis(paper.setup)),
                               ("detailed mesh", detailed, TimeAxis(40 / C + 6e-9, 10e-12, 4096))):
        args = scene_inputs(scene, axis)
        name = f"{label}: {args[0].count} facets x {len(args[1])} det x {axis.n_bins} bins"
        for method in ("deposit", "erf"):
            erf = method == "erf"  # the deposit evaluates no erf lanes: no probe for it
            out.append(Example(f"{name}, {method}", (lambda a: lambda be: a)(args + (method,)),
                               1e-3, hist_err, work=erf_lanes(*args) if erf else 0.0,
                               unit="erf lanes" if erf else ""))
    return out


def examples(size):
    from ..physics.scene import paper_scene
    hist_err = lambda a, b: relative_error(a[0], b[0])  # noqa: E731
    if size == "bench":
        return _bench_examples(hist_err)
    scene = paper_scene(facet_size_m=0.07 if size == "tiny" else 0.02)  # tiny: a partial chunk
    args = scene_inputs(scene, _window(scene, 10e-12))  # 10 ps bins: 8 sub-bins per bin
    n_pad = -(-args[0].count // FACET_CHUNK) * FACET_CHUNK
    inputs = lambda be: args  # noqa: E731
    out = [Example("paper rectangle: histograms, deposit", inputs, 1e-3, hist_err),
           Example("paper rectangle: histograms, erf", lambda be: args + ("erf",), 1e-3,
                   hist_err),
           Example("paper rectangle: contributing path span (m)", inputs, 1e-5, _span_error),
           Example("one detector per group, deposit", inputs, 1e-3, hist_err,
                   max_alloc_bytes=4 * n_pad),
           Example("one detector per group, erf", lambda be: args + ("erf",), 1e-3, hist_err,
                   max_alloc_bytes=4 * n_pad)]
    out += _occlusion_examples(args, hist_err) + _paired_examples(scene, size, hist_err, n_pad)
    out += _patch_example(size, hist_err)
    if size == "check":  # 1 ps bins: one sub-bin per bin, 363 taps
        fine = scene_inputs(scene, _window(scene, 1e-12))
        out.append(Example("paper rectangle at 1 ps, deposit", lambda be: fine, 1e-3, hist_err))
    return out


def _patch_example(size, hist_err):
    """A 4 x 4 patch of spots in one pass (ROWS_MIN_DETECTORS) on a short window: a CPU device
    fuses paths and deposit (`deposit_direct`), one laser and confocal (PAIRED); with an
    occlusion mask the paths come first and the deposit takes one detector per work item
    (`deposit_rows`; the groups of one above take the atomic `deposit`)."""
    from ..physics import layouts
    from ..physics.scene import paper_scene
    spots = layouts.spad_patch((-1.0, 0.0, 0.0), (4, 4), (0.1, 0.1))
    scene = paper_scene(facet_size_m=0.07 if size == "tiny" else 0.02, detector_spots=spots)
    args = scene_inputs(scene, _window(scene, 10e-12))
    confocal = scene_inputs(scene, _window(scene, 10e-12, laser=spots))
    confocal = confocal[:2] + (np.array(spots),) + confocal[3:]
    mask = (np.arange(len(spots) * args[0].count).reshape(len(spots), -1) % 3) != 0
    fixed = lambda a: lambda be: a  # noqa: E731
    return [Example("4 x 4 patch: histograms, deposit", fixed(args), 1e-3, hist_err),
            Example("4 x 4 patch: contributing path span (m)", fixed(args), 1e-5, _span_error),
            Example("4 x 4 patch, confocal: histograms, deposit", fixed(confocal), 1e-3,
                    hist_err),
            Example("4 x 4 patch, occlusion mask: histograms, deposit",
                    fixed(args + ("deposit", mask)), 1e-3, hist_err)]


def _occlusion_examples(args, hist_err):
    """A visibility mask (every third (detector, facet) pair hidden) with both methods, a
    glossy (GGX) and a retroreflective target (a lobe wide enough to vary across the paper's
    laser-detector angles): the kernel's occlusion and reflectance branches."""
    from ..physics.reflectance import GGX, Retroreflective
    facets, n_det = args[0], len(args[1])
    mask = (np.arange(n_det * facets.count).reshape(n_det, -1) % 3) != 0
    glossy = args[:7] + (GGX(specular=0.6, roughness=0.3, diffuse=0.2),)
    retro = args[:7] + (Retroreflective(retro=0.7, width_rad=0.05, diffuse=0.2),)
    return [Example("occlusion mask, deposit", lambda be: args + ("deposit", mask), 1e-3,
                    hist_err),
            Example("occlusion mask, erf", lambda be: args + ("erf", mask), 1e-3, hist_err),
            Example("glossy GGX target, deposit", lambda be: glossy, 1e-3, hist_err),
            Example("glossy GGX target, erf", lambda be: glossy + ("erf",), 1e-3, hist_err),
            Example("retroreflective target, deposit", lambda be: retro, 1e-3, hist_err)]


def _paired_examples(scene, size, hist_err, n_pad):
    """Each detector its own laser spot (-D PAIRED=1): confocal-like (laser = detector spot) and
    paired (the spots reversed, shifted along the wall), on time axes that cover their paths;
    one detector per group (det0 > 0 indexes lasers[d]) and, in "check", a glossy target."""
    from ..physics.reflectance import GGX
    spots, fixed, out = scene.setup.detector_spots, (lambda a: lambda be: a), []
    for label, lasers in (("confocal", spots), ("paired", spots[::-1] + [0.4, 0.0, 0.1])):
        args = scene_inputs(scene, _window(scene, 10e-12, laser=lasers))
        args = args[:2] + (np.array(lasers),) + args[3:]
        out += [Example(f"{label}: histograms, deposit", fixed(args), 1e-3, hist_err),
                Example(f"{label}: one detector per group, erf", fixed(args + ("erf",)), 1e-3,
                        hist_err, max_alloc_bytes=4 * n_pad),
                Example(f"{label}: contributing path span (m)", fixed(args), 1e-5, _span_error)]
        if size == "check":
            glossy = args[:7] + (GGX(specular=0.6, roughness=0.3, diffuse=0.2), "erf")
            out.append(Example(f"{label}: glossy GGX target, erf", fixed(glossy), 1e-3,
                               hist_err))
    return out


OP = Operation(
    "forward", "forward", opencl, numpy, examples,
    tolerance_note="histograms 1e-3 of the peak: paths of ~10 m round to ~1e-6 m in float32, "
    "1e-4 of the pulse sigma; bin widths are exact (edges from one base); erf errs ~1e-6 "
    "against a bin's erf difference of ~0.03. Deposit: a linear split between sub-bins of "
    "sigma / 24 errs by at most (dsub / sigma)^2 / 8 = 2e-4 of the peak (measured 1.2e-5 to "
    "1.5e-5); the fixed-point sums keep 2^-40 of a detector's weight. Path span 1e-5 m: float32 "
    "paths of ~10 m. Paired and confocal layouts: the same tolerances, for the same reasons: "
    "each (facet, detector) runs the same float32 arithmetic on paths of the same size, only "
    "the laser spot comes from lasers[d].",
    bound="deposit: atomics (or, many detectors on a CPU, each detector's read-add-writes) "
    "and FMA (one correlation per sub-bin phase); erf: exp")
