"""nl.locate given the histograms themselves where the filtered signals belong (no `raw`):
they still hold white bin-to-bin noise, which filter.looks_unfiltered tells from the Gauss
filter's output, and they are filtered first and kept as `raw`, with a warning. Filtered
signals, from the host or the device, pass as they are; so do coarse bins, where the filter's
sigma spans under a few bins and the two cannot be told apart."""
import dataclasses
import warnings

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.core.paths import TimeAxis
from nlos_cl.localization.filter import looks_unfiltered
from nlos_cl.ops.signals import as_signals

GRID = nl.Grid((2.0, 0.5, 0.0), (4 / 128, 4 / 128, 0.01), (128, 128, 1))


@pytest.fixture(scope="module")
def clean(runtime):
    axis = TimeAxis(40 / 299_792_458.0, 10e-12, 4096)
    return nl.simulate(nl.paper_scene(facet_size_m=0.02), axis, backend=runtime)


def _located(*args, **kwargs):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        loc = nl.locate(*args, **kwargs)
    return loc, [str(w.message) for w in caught]


def test_the_histograms_are_filtered_first_and_kept_as_raw(clean):
    noisy = nl.add_noise(clean, 10.0, seed=3)  # device Signals, as the README makes them
    host = noisy.histograms()
    told, told_notes = _located(nl.gauss_filter(noisy), GRID, raw=noisy)
    for given in (noisy, host):  # on the device, and from the host
        assert looks_unfiltered(as_signals(given))
        loc, notes = _located(given, GRID)
        assert any(n.startswith("signals: these rows still hold") for n in notes)
        assert not any(n.startswith("signals:") for n in told_notes)
        np.testing.assert_allclose(loc.position, told.position, atol=1e-6)
    assert np.linalg.norm(told.position[:2] - [4.0, 2.0]) < 0.05


def test_filtered_signals_pass_as_they_are(clean):
    noisy = nl.add_noise(clean, 10.0, seed=3)
    for h_s in (0.3e-9, 0.65e-9):  # the paper's h, and a user's narrower filter
        filtered = nl.gauss_filter(noisy, h_s)
        assert filtered.filtered_h_s == h_s and not looks_unfiltered(filtered)
        # the rows themselves, measured (the filter's own output is not read at all)
        assert not looks_unfiltered(dataclasses.replace(filtered, filtered_h_s=None))
        assert not looks_unfiltered(as_signals(filtered.histograms()))
    assert not looks_unfiltered(clean)  # noise-free: smooth at the filter's scale (not told)


def test_coarse_bins_are_not_judged(runtime):
    axis = TimeAxis(40 / 299_792_458.0, 250e-12, 256)  # the filter's sigma: under one bin
    noisy = nl.add_noise(nl.simulate(nl.paper_scene(facet_size_m=0.05), axis,
                                     backend=runtime), 10.0, seed=0)
    assert not looks_unfiltered(noisy)
