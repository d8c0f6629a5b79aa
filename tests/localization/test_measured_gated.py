"""Records taken through a gate (localization.measured.gated): the bins where the detector was
off hold exact zeros, which are not measurements. CC-SOCR's counts are zero around a block of
~800-1,300 a bin (its README: "bins before ~300 are gated to zero"); read as measured, a fit
with any background misses them by the whole level, and the filter reads each gate edge as a
return."""
import warnings

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.localization.measured import gated


def test_a_gated_block_is_found_and_a_return_on_a_dark_record_is_not():
    rng = np.random.default_rng(0)
    n = 400
    block = np.zeros(n)
    block[120:300] = rng.poisson(800.0, 180)  # CC-SOCR-like: zeros around an ambient block
    t = np.arange(n)
    dark_return = rng.poisson(5e4 * np.exp(-0.5 * ((t - 200) / 3.0) ** 2))  # no ambient
    coarse = np.zeros(n)
    coarse[200:202] = [3000, 1200]  # 1 ns bins: the return fills two bins from nothing
    ambient = rng.poisson(50.0, n).astype(float)  # light everywhere: nothing gated
    late_only = np.zeros(n)
    late_only[:250] = rng.poisson(40.0, 250)  # gated at the end only
    first, last = gated.gate_bounds(np.stack([block, dark_return, coarse, ambient, late_only]))
    assert (first[0], last[0]) == (120, 299)
    assert (first[1], last[1]) == (0, n - 1)  # rises through small counts: light, not a gate
    assert (first[2], last[2]) == (0, n - 1)
    assert (first[3], last[3]) == (0, n - 1)
    assert (first[4], last[4]) == (0, 249)


def test_the_filters_input_fills_a_gates_outside_with_its_edge_level():
    data = np.zeros((2, 100))
    data[0, 30:70] = 100.0
    data[0, 30:38] = 50.0  # the level just inside the first edge
    data[1] = 7.0  # no zero: nothing gated, nothing copied
    filled = gated.ungated(data)
    assert np.all(filled[0, :30] == 50.0) and np.all(filled[0, 70:] == 100.0)
    assert np.array_equal(filled[1], data[1]) and np.all(data[0, :30] == 0)  # input kept
    assert gated.ungated(data[1:]) is None


@pytest.mark.parametrize("ambient_hz", [1e5, 1e6])  # ~27 and ~271 counts a bin
def test_a_plate_recorded_through_a_tight_gate_is_located(ambient_hz):
    """The paper's plate in counts, each record gated 30 bins before its return's peak to 60
    after: located as the whole record is (before: 0.36 m off at 27 counts a bin, a box;
    0.11 m at 271, the fit's deviance 23 per degree of freedom)."""
    scene = nl.paper_scene()
    counter = nl.PhotonCounter(n_pulses=80e6 * 3000 / 44234, ambient_rate_hz=ambient_hz)
    counts = counter.counts(nl.simulate(scene).histograms(), seed=2)
    data = np.asarray(counts.data).copy()
    for r, peak in enumerate(data.argmax(axis=1)):
        data[r, :peak - 30], data[r, peak + 60:] = 0, 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        target = nl.locate_capture(counts.with_data(data)).points[0].location.targets[0]
    assert np.linalg.norm(np.asarray(target.position) - [4.0, 2.0, 0.0]) < 0.03
    assert target.fit.diagnostics["misfit_ratio"] < 1.3


def test_a_gated_capture_says_so_in_its_processing():
    """`processing` (the JSON's) names the gated rows and where their gates lie; a capture
    without gates has no such entry."""
    scene = nl.paper_scene()
    counter = nl.PhotonCounter(n_pulses=80e6 * 3000 / 44234, ambient_rate_hz=1e6)
    counts = counter.counts(nl.simulate(scene).histograms(), seed=2)
    data = np.asarray(counts.data).copy()
    data[:, :500], data[:, 800:] = 0, 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gated_point = nl.locate_capture(counts.with_data(data)).points[0]
        plain_point = nl.locate_capture(counts).points[0]
    report = gated_point.processing["gated"]
    assert report["rows"] == report["of"] == 3
    assert (report["first_bin_median"], report["last_bin_median"]) == (500, 799)
    assert "gated" not in (plain_point.processing or {})
