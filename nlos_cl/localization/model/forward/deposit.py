"""The host model's deposit (model.batch, model.host_shapes, model.derivatives): the forward
op's fast path (ops/forward.py: deposit + correlation) in float64 NumPy. Each point's weight is
split linearly between the two sub-bins (at most sigma / SUB_BINS_PER_SIGMA wide) around its
path, then correlated per sub-bin phase with the bin-integrated pulse; the split errs by <=
(dsub / sigma)^2 / 8 = 2e-4 of the peak (the kernel's bound)."""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ....ops.forward import REACH_SIGMAS


def deposit_bins(path, weight, edge0, dpath, sigma, n_bins, os_, cache=None, seg=None):
    """hist (B, D, n): bin k of detector d covers paths edge0[b, d] + [k, k + 1) dpath[d] and
    receives w (erf(z_hi) - erf(z_lo)) from each point (path, weight: (D, B, N); or, with
    `seg`, (D, M): the B rows' points one after another, seg (B,) how many each row has).
    cache: a dict the problem keeps the taps in (they depend only on the pulse width)."""
    plan = split(path, weight, edge0, dpath, sigma, n_bins, os_, seg)
    dep = deposit(plan, weight.reshape(-1).take(plan.kept)[None])[0]
    return correlate(dep, taps_of(dpath / os_, sigma, plan.pad, os_, {} if cache is None
                                else cache), n_bins)


class Split(NamedTuple):
    """Where the deposit puts each point (`split`): the window's pad (bins each side), the
    points inside it (`ok`, a mask of path's shape; `kept`, the same as flat indices), their
    flat (D, B, sub-bin) row and fraction t towards the next sub-bin, and the deposit's shape
    (D, B, n + 2 pad, os)."""

    pad: int
    ok: np.ndarray
    row: np.ndarray
    t: np.ndarray
    shape: tuple
    kept: np.ndarray


def split(path, weight, edge0, dpath, sigma, n_bins, os_, seg=None) -> Split:
    """The linear split of points (path, weight: (D, B, N), or (D, M) with seg (B,) the
    number of points of each row, one row's after another: no padding to the largest row)
    between the two sub-bins (at most sigma / SUB_BINS_PER_SIGMA wide, os a bin) around each
    path, on a window padded by the widest pulse's reach (REACH_SIGMAS). The deposit's rows
    and each one's order of points are the same in both forms (so are its sums, bit for
    bit). The kept points are gathered by their flat indices (np.take: a boolean mask's
    gather cost ~3.5x as much) and each point's row is its (D, B) row's start repeated over
    the points it keeps (a gather of per-point starts cost more than the rest of the split)."""
    n_det = len(dpath)
    n_b = path.shape[1] if seg is None else len(edge0)
    reach = REACH_SIGMAS * float(np.max(sigma))
    pad = math.ceil(reach / float(np.min(dpath))) + 1  # bins each side of the window
    length = (n_bins + 2 * pad) * os_
    base = edge0.T - pad * dpath[:, None]  # (D, B): sub-bin 0's lower edge
    if seg is None:
        u = path - base[:, :, None]  # in place, and t and the rows for the kept points only
    else:  # each row's points minus that row's edge, a slice at a time
        u = np.empty_like(path)
        ends = np.cumsum(seg)
        for b, (lo, hi) in enumerate(zip(ends - seg, ends)):
            np.subtract(path[:, lo:hi], base[:, b:b + 1], out=u[:, lo:hi])
    u *= (os_ / dpath).reshape((n_det,) + (1,) * (path.ndim - 1))
    u -= 0.5  # from sub-bin centres
    j = np.floor(u)
    ok = weight > 0
    ok &= j >= 0
    ok &= j < length - 1
    kept = np.flatnonzero(ok)
    j, t = j.reshape(-1).take(kept), u.reshape(-1).take(kept)
    t -= j
    # each (D, B) row's first flat index, and so the number of kept points in each row
    firsts = np.arange(n_det * n_b) * path.shape[-1] if seg is None else \
        (np.arange(n_det)[:, None] * path.shape[1] + (np.cumsum(seg) - seg)).reshape(-1)
    per_row = np.diff(np.searchsorted(kept, firsts), append=len(kept))
    row = np.repeat(np.arange(n_det * n_b) * length, per_row) + j.astype(np.int64)
    return Split(pad, ok, row, t, (n_det, n_b, n_bins + 2 * pad, os_), kept)


def deposit(plan: Split, values) -> np.ndarray:
    """(E, D, B, n + 2 pad, os): each of E rows of values (E, N) over the points `plan.ok`
    keeps, split between its sub-bin (1 - t) and the next (t), in one pair of bincounts."""
    values = np.asarray(values, np.float64)
    size = math.prod(plan.shape)
    rows = (plan.row[None] + (np.arange(len(values)) * size)[:, None]).reshape(-1)
    upper = values * plan.t[None]
    dep = np.bincount(rows, (values - upper).reshape(-1), minlength=len(values) * size)
    # the upper share in row + 1: a (D, B) row's last sub-bin has none (j < length - 1)
    dep[1:] += np.bincount(rows, upper.reshape(-1), minlength=len(values) * size)[:-1]
    return dep.reshape((len(values),) + plan.shape)


def correlate(dep, taps, n_bins) -> np.ndarray:
    """(..., B, D, n) from a deposit (..., D, B, n + 2 pad, os) and per-phase taps (D, B, os,
    2 pad + 1): hist[k] = sum over i, p of dep[k + i, p] taps[p, i] (sub-bin (k + i) os + p).
    The phases first, as one stacked matrix product m[j, i] = sum_p dep[j, p] taps[p, i],
    then hist[k] = sum_i m[k + i, i] (a strided diagonal): 3-5x faster than one einsum over
    the strided windows (0.31 -> 0.06 ms for 2 pieces of 8 detectors, 36 phases, 13 taps),
    the same sums in another order (within 2e-15 of the peak). Only the bins any row deposits
    into are multiplied (`_used`): a target's return fills a fifth of the observation's window
    (median over a scenario draw's 1,920 calls: 0.18), and the product over the rest, zeros,
    was 60 % of a 56-spot, two-target locate."""
    width = taps.shape[-1]
    shape = (*dep.shape[:-4], dep.shape[-3], dep.shape[-4], n_bins)
    span = _used(dep)
    if span is None:
        return np.zeros(shape)
    lo, hi = span
    k0, k1 = max(lo - width + 1, 0), min(hi, n_bins)  # the bins those rows reach
    hi = min(hi, k1 + width - 1)
    m = np.zeros((*dep.shape[:-2], k1 - k0 + width - 1, width))  # rows k0 .. k1 + width - 2
    m[..., lo - k0:hi - k0, :] = np.matmul(dep[..., lo:hi, :], taps)
    st = m.strides
    diagonal = np.lib.stride_tricks.as_strided(
        m, (*m.shape[:-2], k1 - k0, width), (*st[:-2], st[-2], st[-2] + st[-1]),
        writeable=False)
    out = np.zeros(shape)
    out[..., k0:k1] = np.swapaxes(diagonal.sum(axis=-1), -2, -3)
    return out


def _used(dep):
    """(first, last + 1) of the deposit's bin rows (axis -2) that any row deposits into, or
    None where it is all zeros."""
    used = np.flatnonzero(dep.any(axis=-1).reshape(-1, dep.shape[-2]).any(axis=0))
    return None if not len(used) else (int(used[0]), int(used[-1]) + 1)


WHOLE_TABLES = 8  # whole taps tables taps_of remembers by their scales (bounded memory)


def taps_of(dsub, sigma, pad, os_, cache):
    """(D, B, os, 2 pad + 1): what a unit weight at the centre of phase p of the sub-bins i
    bins after bin k's window start puts into bin k: erf((m + os - 1/2) s) - erf((m - 1/2) s),
    m = (pad - i) os - p, s = dsub / (sqrt 2 sigma); erf evaluated once per distinct m, and
    once per distinct s: a Jacobian's plates share their unmoved plate's pulse width, so
    `cache` ((pad, s) -> taps; "tables": the last WHOLE_TABLES results by their scales) has
    them from the residual call before. The result is read-only (it may be remembered)."""
    from ....core.erf import (
        erf,  # not SciPy's: its import is a seventh of a one-shot locate
    )
    scale = dsub[:, None] / (math.sqrt(2.0) * sigma[None, :])  # (D, B)
    if len(cache) > 256:  # before the look-up: clearing after it lost taps this call reads
        cache.clear()  # (the tables too: bounded memory)
    # A Jacobian's plates share one width, and its rows the residual call's: the last
    # WHOLE_TABLES tables are remembered by their scales too (np.unique and the stack were
    # ~50 us of a ~0.5 ms call: model.batch's per-call overhead)
    tables = cache.setdefault("tables", {})
    whole = (pad, scale.shape, scale.tobytes())
    if whole in tables:
        return tables[whole]
    # the distinct scales and each one's index, in first-seen order (np.unique sorts: a
    # third of this function's time on a warm fit's few dozen scales)
    index = {}
    which = np.array([index.setdefault(v, len(index)) for v in scale.ravel().tolist()])
    values = list(index)
    new = [v for v in values if (pad, v) not in cache]
    if new:
        m = (pad - np.arange(2 * pad + 1))[None, :] * os_ - np.arange(os_)[:, None]  # (os, span)
        lowest = int(m.min())
        grid = np.arange(lowest, int(m.max()) + os_ + 1) - 0.5
        e = erf(np.array(new)[:, None] * grid)
        cache.update(((pad, v), taps) for v, taps in zip(new, e[:, m - lowest + os_]
                                                          - e[:, m - lowest]))
    table = np.stack([cache[(pad, v)] for v in values])
    out = table[which.reshape(scale.shape)]
    out.flags.writeable = False
    if len(tables) >= WHOLE_TABLES:
        tables.clear()
    tables[whole] = out
    return out
