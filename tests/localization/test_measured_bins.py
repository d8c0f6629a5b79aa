"""Dead and hot TDC bins (measured.bins) against their definitions, on captures of more
histograms than one pass of hot_bins reads (bins.ROWS_A_PASS): a bin is dead or hot only if it is so in
every histogram, the last one included."""
import numpy as np
import pytest

from nlos_cl.localization.measured import bins


def _hot_by_definition(data, counts):
    centre, near = data[:, 1:-1], np.maximum(data[:, :-2], data[:, 2:])
    sigma = np.sqrt(np.maximum(near, 1.0)) if counts else np.stack(
        [bins._sigma(row[None], None, False)[0] for row in data])
    return np.flatnonzero(np.all(centre - near > bins.HOT_SIGMA * sigma, axis=0)) + 1


def _dead_by_definition(data, counts):
    zero = ~np.any(data != 0, axis=0)
    zero[[0, -1]] = False
    k = np.flatnonzero(zero)
    left, right = np.abs(data[:, k - 1]), np.abs(data[:, k + 1])
    ok = ((left.sum(axis=0) >= bins.DEAD_MIN_COUNTS) & (right.sum(axis=0) >= bins.DEAD_MIN_COUNTS)
          if counts else ((left > 0) & (right > 0)).mean(axis=0) >= 0.5)
    return k[ok]


@pytest.mark.parametrize("counts", [True, False])
def test_bins_hot_or_dead_in_every_histogram_and_only_those(counts):
    rng = np.random.default_rng(3)
    n = 2 * bins.ROWS_A_PASS + 37
    data = rng.poisson(5.0, (n, 300)).astype(np.float64)
    if not counts:
        data += rng.normal(0.0, 0.1, data.shape)
    data[:, [40, 41, 200]] += 200.0  # hot in every histogram (41 is 40's neighbour: not hot)
    data[:, 120] += 200.0
    data[-1, 120] -= 200.0  # hot in all but the last histogram: not hot
    data[:, [60, 250]] = 0.0  # dead in every histogram
    data[:, 90] = 0.0
    data[-1, 90] = 3.0  # zero in all but the last: not dead
    data[:, 0] = 0.0  # the record's first bin: a gate edge
    assert np.array_equal(bins.hot_bins(data, counts), [200])
    assert np.array_equal(bins.hot_bins(data, counts), _hot_by_definition(data, counts))
    assert np.array_equal(bins.dead_bins(data, counts), [60, 250])
    assert np.array_equal(bins.dead_bins(data, counts), _dead_by_definition(data, counts))
    few = data[:bins.HOT_MIN_HISTOGRAMS - 1]
    assert bins.hot_bins(few, counts).size == 0
