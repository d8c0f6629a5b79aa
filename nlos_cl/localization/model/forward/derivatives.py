"""Analytic derivatives of the host plate model (model.batch.HostProblem): d(histograms) /
d(x, y, z, width, height, yaw) of each plate at its frozen cell statistics (pull-in, blur,
shift), what model.fit's forward differences with borrowed statistics approximate with a 2 mm
step. Within 0.1 % of central differences (tests/localization/model/test_model_derivatives.py). The covariance
uses them; the LM's Jacobian does not, being cheaper as differences on the host (the comment
at model.fit.ANALYTIC says what was measured).
"""
from __future__ import annotations

import math
import time

import numpy as np

from ..shapes import plate
from .batch import _paths, _plate_points
from .deposit import correlate, deposit, split, taps_of


def column_derivatives(problem, rows):
    """(B, 6, D, n): d(column)/d(parameter) of each plate of rows (B, 6), analytic, at
    the plate's own (frozen) cell statistics: what `column_batch(rows + step, like=rows)`
    differences give, without the step (`plate_derivatives`). None where this model has
    no derivative: a reflectance factor (its slope is not modelled here)."""
    if problem._factor is not None:
        return None
    t = time.perf_counter()
    obs = problem.obs
    rows = np.atleast_2d(np.asarray(rows, np.float64))
    stats = problem._statistics_of(rows)
    points, normal, area, stats = _plate_points(rows, problem.lattice, problem._stat_spots,
                                                obs.laser, stats)
    _, blur2, shift = stats
    sigma = np.sqrt(obs.sigma0_m ** 2 + blur2 - obs.box_excess_m2)
    points = points.reshape(len(rows), -1, 3)
    path, weight, dpath, dweight = plate_derivatives(rows, points, normal, area / 4.0,
                                                     obs.spots, obs.laser)
    out = _deposit_derivatives(path, weight, dpath, dweight,
                               obs.edge0[None] - problem._spread(shift), obs.dpath, sigma,
                               obs.n, problem.os, problem._taps)
    problem.model_s += time.perf_counter() - t
    return np.where(obs.valid[None, None], out.transpose(1, 0, 2, 3), 0.0)


def plate_derivatives(rows, points, normal, area, spots, laser):
    """Analytic d(path) and d(weight) of every point of plates `rows` (B, 6) with respect to
    each plate parameter (x, y, z, width, height, yaw), at frozen cell statistics (each point
    keeps its fractions of the plate's width and height: model.fit's borrowed-statistics
    derivative, without its 2 mm step). points (B, M, 3); normal (B, 3); area (B,) (per
    point). Returns path, weight (D, B, M) as `_paths` gives them, and dpath, dweight
    (6, D, B, M). A point's weight is |v1y| (n . (O - P))+ a / r1^4 |v2y| (n . (S - P))+ / r2^4
    (`_paths`), differentiated factor by factor; where a factor is 0 (the plate edge-on to O
    or a spot) the weight and its derivative are 0."""
    path, weight = _paths(points, normal, area, spots, laser)
    centre = rows[:, None, :3]  # (B, 1, 3)
    yaw, w, h = rows[:, plate.YAW], rows[:, plate.WIDTH], rows[:, plate.HEIGHT]
    zero = np.zeros_like(yaw)
    across = np.stack([-np.sin(yaw), np.cos(yaw), zero], axis=1)  # (B, 3)
    off = points - centre
    a = np.einsum("bmk,bk->bm", off, across)  # the point's offset across the plate (m)
    b = off[..., 2]  # and up it
    v1 = points - laser  # (B, M, 3): O -> P
    v2 = spots[:, None, None, :] - points[None]  # (D, B, M, 3): P -> S
    r1sq = np.einsum("bmk,bmk->bm", v1, v1)
    r2sq = np.einsum("dbmk,dbmk->dbm", v2, v2)
    r1, r2 = np.sqrt(r1sq), np.sqrt(r2sq)
    # dP/dtheta: x, y, z unit vectors; width (a / w) across; height (b / h) up; yaw -a n
    v1_across = np.einsum("bmk,bk->bm", v1, across)
    v1_n = np.einsum("bmk,bk->bm", v1, normal)
    v2_across = np.einsum("dbmk,bk->dbm", v2, across)
    v2_n = np.einsum("dbmk,bk->dbm", v2, normal)
    rows_w, rows_h = w[:, None], h[:, None]
    v1_dp = [v1[..., 0], v1[..., 1], v1[..., 2], v1_across * a / rows_w, v1[..., 2] * b / rows_h,
             -a * v1_n]
    v2_dp = [v2[..., 0], v2[..., 1], v2[..., 2], v2_across * (a / rows_w)[None],
             v2[..., 2] * (b / rows_h)[None], -a[None] * v2_n]
    dpy = [0.0, 1.0, 0.0, across[:, 1, None] * a / rows_w, 0.0, -a * normal[:, 1, None]]
    # the facing factors n . (O - P) and n . (S - P): one number per plate (and spot)
    p0 = points[:, 0]
    facing_o = np.einsum("bk,bk->b", normal, laser - p0)
    facing_s = np.einsum("bk,dbk->db", normal, spots[:, None] - p0[None])
    d_facing_o = [-normal[:, 0], -normal[:, 1], zero, zero, zero,
                  np.einsum("bk,bk->b", across, laser - rows[:, :3])]
    d_facing_s = [-normal[None, :, 0], -normal[None, :, 1], zero[None], zero[None], zero[None],
                  np.einsum("bk,dbk->db", across, spots[:, None] - rows[None, :, :3])]
    d_area = [0.0, 0.0, 0.0, 1.0 / rows_w, 1.0 / rows_h, 0.0]  # d log(area)
    sign1 = np.sign(v1[..., 1])
    sign2 = np.sign(v2[..., 1])
    safe_o = np.where(facing_o > 0, facing_o, 1.0)[:, None]
    safe_s = np.where(facing_s > 0, facing_s, 1.0)[..., None]
    dpath = np.empty((plate.N_PARAMS,) + path.shape)
    dweight = np.empty_like(dpath)
    for i in range(plate.N_PARAMS):
        dr1sq = 2.0 * v1_dp[i]
        dr2sq = -2.0 * v2_dp[i]
        dpath[i] = v1_dp[i] / r1 - v2_dp[i] / r2
        dlog = (sign1 * dpy[i] / np.abs(v1[..., 1]) + np.asarray(d_facing_o[i])[:, None] / safe_o
                + d_area[i] - 2.0 * dr1sq / r1sq)[None]
        dlog = dlog - sign2 * dpy[i] / np.abs(v2[..., 1]) \
            + np.asarray(d_facing_s[i])[..., None] / safe_s - 2.0 * dr2sq / r2sq
        dweight[i] = weight * dlog
    return path, weight, dpath, dweight



def _deposit_derivatives(path, weight, dpath, dweight, edge0, dpath_m, sigma, n_bins, os_,
                         cache=None):
    """(P, B, D, n): d hist / d theta = sum over points of dweight K(s) + weight dpath K'(s),
    K the bin-integrated pulse (deposit.taps_of) and K' its derivative in the point's
    path; both terms deposited by the same linear split (deposit.split) and correlated per
    phase."""
    plan = split(path, weight, edge0, dpath_m, sigma, n_bins, os_)
    n_p = len(dpath)
    # the P dweight deposits, then the P (weight x dpath) ones, in one pair of bincounts
    kept, n_all = plan.kept, weight.size  # the kept points by their flat indices (np.take)
    dep = deposit(plan, np.concatenate([dweight.reshape(-1, n_all).take(kept, axis=1),
                                        weight.reshape(-1).take(kept)
                                        * dpath.reshape(-1, n_all).take(kept, axis=1)]))
    dsub = dpath_m / os_
    taps = taps_of(dsub, sigma, plan.pad, os_, {} if cache is None else cache)
    return (correlate(dep[:n_p], taps, n_bins)
            + correlate(dep[n_p:], _slope_taps(dsub, sigma, plan.pad, os_), n_bins))


def _slope_taps(dsub, sigma, pad, os_):
    """(D, B, os, 2 pad + 1): d/ds of `taps_of`' values for a point at path s: the tap is
    erf((m + os - 1/2) c) - erf((m - 1/2) c) with m = (edge - s) / dsub, c = dsub / (sqrt 2
    sigma), so its slope is -(c / dsub) (2 / sqrt pi) (exp(-((m + os - 1/2) c)^2) -
    exp(-((m - 1/2) c)^2))."""
    scale = dsub[:, None] / (math.sqrt(2.0) * sigma[None, :])  # (D, B)
    m = (pad - np.arange(2 * pad + 1))[None, :] * os_ - np.arange(os_)[:, None]  # (os, span)
    hi = (m + os_ - 0.5)[None, None] * scale[..., None, None]
    lo = (m - 0.5)[None, None] * scale[..., None, None]
    factor = -(scale / dsub[:, None]) * (2.0 / math.sqrt(math.pi))
    return factor[..., None, None] * (np.exp(-hi * hi) - np.exp(-lo * lo))
