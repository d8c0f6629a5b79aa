"""The model fit's observation reads a frame once, as stored, and stays bounded on long
records (model.data, Locator.__call__): a 1,024 x 60,000-bin SPAD frame had spent ~8 s of a
12 s locate on float64 copies, a second read of the filtered rows, an upload of the raw
histograms only to read them back, and full-row medians."""
import math
import warnings

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.localization.estimate import Scored
from nlos_cl.localization.model import ModelEstimator
from nlos_cl.localization.model.forward import data
from nlos_cl.ops.backend import NumpyBackend, read_values
from nlos_cl.ops.signals import Signals

from conftest import paper_frame


def _observe(filtered, raw, host_rows=None):
    return ModelEstimator().observation(Scored(filtered.backend, None, nl.Grid(), False,
                                               filtered.n_detectors, filtered, raw,
                                               host_rows=host_rows))


def test_reads_keep_the_stored_dtype_and_the_fallback_copies(runtime):
    values = np.arange(12, dtype=np.float64).reshape(3, 4)
    handle = runtime.from_numpy(values)
    assert runtime.read(handle).dtype == np.float32  # as the device holds it
    assert np.array_equal(runtime.read(handle), values)
    assert NumpyBackend().read(values) is values  # already on the host: no copy

    class Old:  # a backend written before `read`
        def to_numpy(self, h):
            return np.array(h, dtype=np.float64)
    assert read_values(Old(), values).dtype == np.float64


def test_the_observation_of_float32_rows_is_the_float64_one(runtime):
    """The filtered rows as the device holds them (float32) against their float64 copy: the
    same windows, and samples and noise within float32's rounding."""
    filtered, raw = paper_frame(runtime)
    as_read = _observe(filtered, raw, host_rows=runtime.read(filtered.handle))
    as_before = _observe(filtered, raw, host_rows=runtime.to_numpy(filtered.handle))
    assert np.array_equal(as_read.path0, as_before.path0)
    assert np.array_equal(as_read.valid, as_before.valid)
    assert np.allclose(as_read.y, as_before.y, rtol=0, atol=1e-6 * np.abs(as_before.y).max())
    assert np.allclose(as_read.noise, as_before.noise, rtol=1e-5)


def test_raw_histograms_stay_on_the_host_and_their_scale_is_honoured(runtime):
    """Host raw histograms are not uploaded (nor copied: the user's array is referenced, read
    only); the samples filtered from them are put in the filtered rows' units before the
    floor measured on those rows comes off (each Signals has its own power-of-two scale: a
    raw frame scaled 4x against its filtered rows left the floor off by 4x)."""
    from nlos_cl.localization.locator import _raw_for
    filtered, raw_signals = paper_frame(runtime)
    host = raw_signals.histograms()
    before = host.data.copy()
    raw = _raw_for(ModelEstimator(), host, runtime)
    assert isinstance(raw.backend, NumpyBackend) and raw.handle is host.data
    on_device = _observe(filtered, raw_signals)
    on_host = _observe(filtered, raw)
    assert np.array_equal(host.data, before)  # nothing the user gave is modified
    for got in (on_host,):
        assert np.allclose(got.y, on_device.y, rtol=0, atol=1e-5 * np.abs(on_device.y).max())
        assert np.allclose(got.noise, on_device.noise, rtol=1e-4)
    rescaled = Signals(NumpyBackend(), host.data / (4.0 * raw_signals.scale_w),
                       4.0 * raw_signals.scale_w, host.layout)
    again = _observe(filtered, rescaled)
    assert np.allclose(again.y, on_device.y, rtol=0, atol=1e-5 * np.abs(on_device.y).max())
    assert np.allclose(again.noise, on_device.noise, rtol=1e-4)


def _windows_row_by_row(filtered, noise, margin_bins, frac, n_sigma=6.0):
    """signal_windows as it was written, one row at a time (its twin)."""
    from nlos_cl.core.stats import row_median
    out = []
    for row, s, floor in zip(filtered, noise, row_median(filtered)):
        row = row - floor
        above = np.flatnonzero(row > max(n_sigma * s, frac * row.max()))
        if above.size == 0:
            above = np.array([int(np.argmax(row))])
        out.append((int(above[0]) - margin_bins, int(above[-1]) + margin_bins))
    return np.array(out)


@pytest.mark.parametrize("n_rows", [3, 130])
def test_signal_windows_in_blocks_are_the_row_by_row_ones(n_rows):
    rng = np.random.default_rng(n_rows)
    rows = 0.01 * rng.standard_normal((n_rows, 3000))
    at = rng.integers(200, 2800, n_rows)
    rows[np.arange(n_rows), at] += rng.uniform(0.0, 1.0, n_rows)  # some rows: noise only
    rows[0] = 0.0  # a dead row: the peak (bin 0) is its window
    noise = np.full(n_rows, 0.01)
    got = data.signal_windows(rows, noise, 40, 0.05)
    assert np.array_equal(got, _windows_row_by_row(rows, noise, 40, 0.05))


def test_medians_are_bounded_on_long_records_and_exact_below_the_budget():
    rng = np.random.default_rng(0)
    small = rng.standard_normal((8, 60_000))  # the draws' frames: every bin, as np.diff
    assert np.array_equal(data._adjacent_steps(small), np.diff(small, axis=1))
    assert data._every(small).shape == small.shape
    big = np.broadcast_to(small[:1], (1024, 60_000))  # a SPAD record's size
    assert data._every(big).size <= data.MEDIAN_BUDGET
    steps = data._adjacent_steps(big)
    assert steps.size <= data.MEDIAN_BUDGET
    # adjacent pairs: the same noise level as every difference (sd sqrt(2), MAD-estimated)
    assert math.isclose(float(np.median(data._mad_std(steps))) / math.sqrt(2.0), 1.0,
                        rel_tol=0.05)


def test_counts_are_told_from_floats_on_a_sample_first():
    counts = np.random.default_rng(1).poisson(3.0, (4, 5000)).astype(np.float64)
    assert data.looks_like_counts(counts)
    assert data.looks_like_counts(counts / 8.0, 8.0)  # the upload's scale undone
    assert not data.looks_like_counts(counts + 0.25)
    late = counts.copy()
    late[3, 4999] = 0.5  # a float only where the sample does not look: the full pass finds it
    assert not data.looks_like_counts(late)
    assert not data.looks_like_counts(np.zeros((2, 10)))  # no photon at all


def test_strided_medians_locate_as_every_bin_does(runtime, monkeypatch):
    """A 64-detector frame with its medians taken over every bin, and over every 16th (the
    budget lowered so that this frame lies beyond it, as a SPAD record does): the same fit to
    a fraction of its uncertainty."""
    truth = (3.0, 2.0, 0.0)
    spots = nl.layouts.spad_patch((-1.0, 0.0, 0.0), (8, 8), (0.05, 0.05))
    setup = nl.paper_setup(detector_spots=spots)
    mesh = nl.rectangle(0.3, 1.6, centre=truth, normal=(-1, 0, 0))
    clean = nl.simulate(nl.Scene(setup, nl.Target(mesh), truth=truth)).histograms()
    noisy = nl.add_noise(clean, 15, seed=2).histograms()
    grid = nl.Grid.from_ranges(x=(2.0, 4.0), y=(1.0, 3.0), step_m=0.01)
    found = {}
    for budget in (data.MEDIAN_BUDGET, noisy.data.size // 16):
        monkeypatch.setattr(data, "MEDIAN_BUDGET", budget)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            found[budget] = nl.locate(nl.gauss_filter(noisy), grid, estimator="model",
                                      raw=noisy).targets[0]
    every, strided = found.values()
    assert np.linalg.norm(every.position - np.array(truth)) < 0.01
    sd = math.sqrt(float(np.trace(every.covariance)))
    assert np.linalg.norm(strided.position - every.position) < 0.25 * sd


def _windows_by_definition(filtered, noise, margin, frac, n_sigma=6.0):
    """signal_windows as its docstring defines it, row by row in float64."""
    floors = data.row_median(data._every(filtered))
    out = []
    for row, floor, sd in zip(filtered.astype(np.float64), floors, noise):
        rows = row - floor
        above = np.flatnonzero(rows > max(n_sigma * sd, frac * rows.max()))
        first, last = (above[0], above[-1]) if above.size else (rows.argmax(), rows.argmax())
        out.append((first - margin, last + margin))
    return np.array(out)


def test_signal_windows_follow_their_definition():
    """The windows found without float64 copies of the rows (rows > level + floor, from the
    maxima of blocks of bins and the first and last block above read bin by bin) are the
    definition's: rows with no bin above (the peak), a floor, the last bin of a partial last
    block and a block's edge included."""
    rng = np.random.default_rng(5)
    rows = (0.1 * rng.standard_normal((150, 3000)) + 0.4).astype(np.float32)  # a floor
    rows[:, 1200:1300] += np.linspace(0.5, 6.0, 150)[:, None].astype(np.float32)
    rows[7] = -1.0  # nothing above: the peak's bin
    rows[9, 10:12] += 9.0  # a lone early spike
    rows[11, 2999] += 20.0  # the last bin, in the partial last block (blocks of 1,024)
    rows[12, [1023, 1024]] += 20.0  # either side of a block's edge
    noise = np.full(len(rows), 0.1)
    got = data.signal_windows(rows, noise, 40, data.ONE_TARGET_FRAC)
    assert np.array_equal(got, _windows_by_definition(rows, noise, 40, data.ONE_TARGET_FRAC))
    assert tuple(got[7]) == (-40, 40) and got[9, 0] == 10 - 40
    assert got[11, 1] == 2999 + 40 and got[12, 1] >= 1024 + 40


def test_raw_filtered_at_the_samples_is_each_windows_dot_product():
    """_filtered_at against its definition: sum over taps of raw[idx + t - half] x taps[t],
    zero outside the record; rows inside, across both ends (clipped samples repeat a bin),
    and one sample a row. (Reading evenly spaced windows as a strided view was tried: 1.8x
    faster on float32 rows, but slower and not bit-identical on the float64 rows a raw SPAD
    frame arrives as.)"""
    rng = np.random.default_rng(2)
    raw = rng.standard_normal((40, 900)).astype(np.float32)
    taps = data.full_gauss_taps(0.3e-9, 10e-12)
    half = (len(taps) - 1) // 2
    k0 = rng.integers(-300, 900, len(raw))
    idx = np.clip(k0[:, None] + 7 * np.arange(30)[None], 0, 899)
    padded = np.pad(raw.astype(np.float64), ((0, 0), (half, half)))
    want = np.array([[padded[d, k:k + len(taps)] @ taps for k in row] for d, row in
                     enumerate(idx)])
    assert np.allclose(data._filtered_at(raw, idx, taps), want, rtol=1e-12, atol=1e-12)
    assert np.allclose(data._filtered_at(raw, idx[:, :1], taps), want[:, :1], rtol=1e-12,
                       atol=1e-12)
