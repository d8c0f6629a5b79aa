"""Photon counts in fine bins are summed into model bins of up to sigma / 3 of the model pulse
(forward.data.counts_group): a sum of Poisson counts is Poisson, so the likelihood stays exact
and the fit sees fewer samples. What neither implementation can fake: every count inside the
window is kept (the groups' sums equal the bins' sums), and the plate found on the grouped
counts is the one found bin by bin, within the fits' own standard deviations."""
import warnings

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.localization.model import ModelEstimator
from nlos_cl.localization.model.forward import data

GRID = nl.Grid.from_ranges(x=(0, 6), y=(0.01, 6), step_m=0.02)


@pytest.mark.parametrize("sigma_m, step_m, group", [(0.0127, 0.0012, 3), (0.0127, 0.003, 1),
                                                    (0.0127, 0.015, 1), (0.1, 0.003, 11)])
def test_groups_stay_within_a_third_of_the_pulse(sigma_m, step_m, group):
    got = data.counts_group(sigma_m, np.full(4, step_m))
    assert got == group and got * step_m <= max(sigma_m / 3, step_m)


def _counts(dt_s, seed=4):
    setup = nl.paper_setup()
    scene = nl.Scene(setup, nl.Target(nl.rectangle(0.3, 1.6, centre=(4.0, 2.0, 0.0))),
                     truth=(4.0, 2.0, 0.0))
    signals = nl.simulate(scene, nl.default_time_axis(setup, dt_s)).histograms()
    counter = nl.PhotonCounter(n_pulses=80e6 * 3000 / 44234, tdc_bin_s=dt_s)
    return counter.counts(signals, seed=seed)


def _histograms(counts):
    return counts.histograms() if hasattr(counts, "histograms") else counts


def _located(counts):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return nl.locate(nl.gauss_filter(counts), GRID, estimator=ModelEstimator(), raw=counts)


def test_grouped_counts_keep_every_count_and_find_the_same_plate(monkeypatch):
    counts = _counts(4e-12)
    hist = _histograms(counts)
    obs = data.poisson_observation(hist.layout, hist.data, hist.data)
    assert np.allclose(obs.dpath, 3 * hist.path_axis().step_m)  # 4 ps: groups of 3
    grouped = _located(counts)
    monkeypatch.setattr(data, "COUNTS_BINS_PER_SIGMA", 1e9)  # one bin a group: as before
    single = _located(counts)
    assert grouped.targets[0].details["likelihood"] == "poisson"
    a, b = grouped.targets[0], single.targets[0]
    sd = np.sqrt(np.diag(a.covariance) + np.diag(b.covariance))
    assert np.all(np.abs(a.position - b.position) <= 3 * sd + 1e-3), (a.position, b.position)
    assert grouped.error_m < 0.05


def test_group_sums_equal_the_bins_they_hold():
    counts = _histograms(_counts(4e-12, seed=7))
    obs = data.poisson_observation(counts.layout, counts.data, counts.data)
    step = counts.path_axis().step_m
    for d in range(len(obs.y)):
        first = int(round((obs.edge0[d] - counts.path_axis().start_m[d]) / step[d]))
        n_valid = int(obs.valid[d].sum())
        assert obs.valid[d, :n_valid].all()  # the record's end cuts only the last groups
        held = counts.data[d, first:first + 3 * n_valid]
        assert np.isclose(obs.y[d, :n_valid].sum(), held.sum())
        assert np.allclose(obs.y[d, :n_valid], held.reshape(-1, 3).sum(axis=1))
