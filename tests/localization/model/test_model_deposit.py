"""model.deposit's correlation and taps against their definitions: the windows are a strided
view and the taps are remembered (by value, and whole tables by their scales), so what a
warm cache returns must be what a cold one computes, and the memory must stay bounded."""
import numpy as np

from nlos_cl.localization.model.forward import deposit


def test_correlate_is_the_sum_over_window_and_phase():
    """hist[..., b, d, k] = sum over i, p of dep[..., d, b, k + i, p] taps[d, b, p, i]."""
    rng = np.random.default_rng(0)
    n_bins, pad, os_ = 11, 3, 4
    dep = rng.standard_normal((2, 3, 5, n_bins + 2 * pad, os_))  # (E, D, B, n + 2 pad, os)
    taps = rng.standard_normal((3, 5, os_, 2 * pad + 1))
    want = np.zeros((2, 5, 3, n_bins))
    for k in range(n_bins):
        for i in range(2 * pad + 1):
            want[..., k] += np.einsum("edbp,dbp->ebd", dep[:, :, :, k + i, :], taps[..., i])
    got = deposit.correlate(dep, taps, n_bins)
    assert np.allclose(got, want, rtol=1e-12, atol=1e-12)
    assert np.allclose(deposit.correlate(dep[1:], taps, n_bins), want[1:], rtol=1e-12,
                       atol=1e-12)  # a slice of rows (model.derivatives' slope rows)


def test_correlate_over_the_used_bins_is_the_whole_sum():
    """Deposits that fill only some bins (a target's return in a long window), at the
    window's start, middle and end, and none at all: correlate multiplies only the bins used
    and returns the whole window's histograms (zeros elsewhere), as the definition."""
    rng = np.random.default_rng(2)
    n_bins, pad, os_ = 40, 3, 4
    taps = rng.standard_normal((3, 5, os_, 2 * pad + 1))
    for lo, hi in [(0, 4), (17, 23), (n_bins + 2 * pad - 5, n_bins + 2 * pad), (9, 10)]:
        dep = np.zeros((2, 3, 5, n_bins + 2 * pad, os_))
        dep[..., lo:hi, :] = rng.standard_normal(dep[..., lo:hi, :].shape)
        want = np.zeros((2, 5, 3, n_bins))
        for k in range(n_bins):
            for i in range(2 * pad + 1):
                want[..., k] += np.einsum("edbp,dbp->ebd", dep[:, :, :, k + i, :], taps[..., i])
        got = deposit.correlate(dep, taps, n_bins)
        assert got.shape == want.shape
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())
    assert not deposit.correlate(np.zeros_like(dep), taps, n_bins).any()


def test_taps_from_a_warm_cache_equal_a_cold_ones_and_the_cache_stays_bounded():
    rng = np.random.default_rng(1)
    dsub = np.array([0.004, 0.004, 0.005])
    cache = {}
    for call in range(40):
        sigma = rng.choice([0.05, 0.06, 0.07, 0.08], size=6) + 0.001 * (call % 11)
        warm = deposit.taps_of(dsub, sigma, 6, 8, cache)
        again = deposit.taps_of(dsub, sigma, 6, 8, cache)  # the whole table, remembered
        cold = deposit.taps_of(dsub, sigma, 6, 8, {})
        assert np.array_equal(warm, cold) and np.array_equal(again, cold)
        assert warm.shape == (3, 6, 8, 13) and not warm.flags.writeable
        assert len(cache["tables"]) <= deposit.WHOLE_TABLES and len(cache) <= 258
    # a tap is erf(z_hi) - erf(z_lo) over one bin (deposit_bins' docstring), so a point's
    # taps over a window wide against the pulse sum to erf(inf) - erf(-inf) = 2
    wide = deposit.taps_of(np.array([0.004]), np.array([0.01]), 40, 8, {})
    assert np.allclose(wide.sum(axis=-1), 2.0, atol=1e-9)
