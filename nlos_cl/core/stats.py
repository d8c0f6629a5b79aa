"""The chi-square quantile every test in nlos_cl uses (the tracker's gates, the model fit's
misfit test), without SciPy: scipy.stats' import (~0.6 s) would be most of a one-shot
`nlos-cl locate`. Newton's method on the regularized incomplete gamma function from the
Wilson-Hilferty start; within 1e-10 (relative) of scipy.stats.chi2.ppf (tests/core/test_stats.py).
And a row median with NumPy's numbers at a tenth of its cost on long rows; a median and
np.unique's values without the numpy.ma import (~7 ms) their first call costs a one-shot
command."""
from __future__ import annotations

import math

import numpy as np

from .constants import TINY
from .errors import require


def unique_sorted(values) -> np.ndarray:
    """np.unique(values): the sorted distinct values of the flattened array, NaNs as one (as
    np.unique's equal_nan). NumPy 2.x's np.unique without return_* imports numpy.ma on its
    first call (~7 ms of a one-shot `nlos-cl locate`); a sort and a comparison of
    neighbours import nothing."""
    flat = np.sort(np.asarray(values).ravel())
    if not flat.size:
        return flat
    if flat.dtype.kind in "fc" and np.isnan(flat[-1]):  # sorted: NaNs last, kept once
        first = int(np.argmax(np.isnan(flat)))
        return np.concatenate([unique_sorted(flat[:first]), flat[first:first + 1]])
    return flat[np.concatenate(([True], flat[1:] != flat[:-1]))]


def median(values) -> float:
    """float(np.median(values)), the same number, without importing numpy.ma: NumPy 2.x's
    median looks for NaNs through np.ma on its first call (~7 ms of a one-shot command). In the
    values' own float type, as np.median (float32 rows: the mean of the middle two in float32);
    integers in float64."""
    flat = np.asarray(values).reshape(-1)
    if flat.dtype.kind not in "fc":
        flat = flat.astype(np.float64)
    n = flat.size
    if n == 0 or not np.isfinite(flat).all():
        return float(np.median(flat))
    part = flat.copy()
    mid = n // 2
    part.partition(mid)
    if n % 2:
        return float(part[mid])
    return float((part[:mid].max() + part[mid]) / flat.dtype.type(2))


def row_median(rows, *, overwrite=False) -> np.ndarray:
    """np.median(rows, axis=1) in float64 (the same numbers for float64 rows; float32 rows are
    averaged in float64, np.median would in float32), ~10x faster on long rows: np.median also
    partitions at the last element to find NaNs (kth=[mid, -1]), which costs 2 ms on 3 x 60,000
    bins where one partition at the middle costs 0.2 ms. Rows holding NaN go to np.median.
    overwrite: rows is a temporary of the caller's, partitioned in place (no copy)."""
    rows = np.asarray(rows, dtype=np.float64)
    n = rows.shape[1]
    if n == 0 or not np.isfinite(rows).all():
        return np.median(rows, axis=1)
    part = rows if overwrite and rows.flags.writeable else rows.copy()
    mid = n // 2
    part.partition(mid, axis=1)
    if n % 2:
        return part[:, mid].copy()
    return 0.5 * (part[:, :mid].max(axis=1) + part[:, mid])  # np.median's mean of the two


def deviance_residuals(y, lam) -> np.ndarray:
    """Signed Poisson deviance residuals of counts y against means lam (same shape, lam > 0):
    sign(y - lam) sqrt(2 (y ln(y / lam) - (y - lam))); their squares sum to the deviance."""
    ylog = np.where(y > 0, y * np.log(np.where(y > 0, y, 1.0) / lam), 0.0)
    return np.sign(y - lam) * np.sqrt(np.maximum(2.0 * (ylog - (y - lam)), 0.0))


def chi2_quantile(probability: float, dof: float) -> float:
    """x with P(chi^2_dof <= x) = probability (0 < probability < 1, dof > 0)."""
    require(0.0 < probability < 1.0, "probability", f"must be in (0, 1), got {probability!r}",
            "pass e.g. 0.999")
    require(dof > 0 and math.isfinite(dof), "dof", f"must be positive, got {dof!r}", "pass >= 1")
    a = 0.5 * dof
    x = max(_wilson_hilferty(probability, dof), 1e-12)
    for _ in range(60):
        f = _lower_gamma_p(a, 0.5 * x) - probability
        density = math.exp((a - 1.0) * math.log(0.5 * x) - 0.5 * x - math.lgamma(a)) * 0.5
        step = f / density if density > 0 else 0.0
        x_next = x - step if x - step > 0 else 0.5 * x
        if abs(x_next - x) <= 1e-13 * x:
            return x_next
        x = x_next
    return x


def _wilson_hilferty(probability: float, dof: float) -> float:
    z = _normal_quantile(probability)
    c = 2.0 / (9.0 * dof)
    return dof * max(1.0 - c + z * math.sqrt(c), 1e-3) ** 3


def _normal_quantile(p: float) -> float:
    """A start for Newton: the normal quantile by bisection on erfc (50 halvings, ~1e-15)."""
    lo, hi = -40.0, 40.0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if 0.5 * math.erfc(-mid / math.sqrt(2.0)) < p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _lower_gamma_p(a: float, x: float) -> float:
    """Regularized lower incomplete gamma P(a, x): the series below a + 1, else 1 - the
    continued fraction of Q (Numerical Recipes' gser / gcf)."""
    if x <= 0.0:
        return 0.0
    log_front = a * math.log(x) - x - math.lgamma(a)
    if x < a + 1.0:
        term = total = 1.0 / a
        n = a
        while abs(term) > 1e-17 * abs(total):
            n += 1.0
            term *= x / n
            total += term
        return total * math.exp(log_front)
    b, c, d = x + 1.0 - a, 1e300, 1.0 / (x + 1.0 - a)
    h, i = d, 1
    while True:
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = TINY if abs(d) < TINY else d
        c = b + an / c
        c = TINY if abs(c) < TINY else c
        d = 1.0 / d
        delta = d * c
        h *= delta
        i += 1
        if abs(delta - 1.0) < 1e-16 or i > 10_000:
            break
    return 1.0 - math.exp(log_front) * h
