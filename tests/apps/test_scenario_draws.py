"""Scenario-suite draws (`nlos-cl reproduce scenarios`) that once failed, re-run alone as the
suite runs them (scenarios.experiment.rerun): each is now within 0.15 m or warned, the goal's
"no failure without a warning" (issue 57), or found outright (policy.rivals, the held centre
of policy.closed, select.best_of)."""
import warnings

import pytest

from nlos_cl.apps.reproduce.scenarios.experiment import rerun


def _row(index, folder):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return rerun(index, folder)


@pytest.mark.parametrize("index", [3, 5, 28])
def test_three_spot_persons_are_close_or_warned(index, tmp_path):
    """Scenario draws 3 (a gated record), 5 (photon counts) and 28 (1 ns bins): a person seen
    by a triangle of 3 spots, answered 0.24, 0.23 and 0.48 m off before the rivals' notice
    with no warning at all."""
    row = _row(index, tmp_path)
    assert row["error_m"] <= 0.15 or row["warned"], row


def test_scenario_36s_oblique_plate_in_counts_is_found(tmp_path):
    """A 1.19 x 1.32 m plate 62 degrees off facing the wall, 30 SPAD spots, photon counts in
    41.5 ps bins: 0.351 m off (a box behind the wrong plate) before, with no warning."""
    row = _row(36, tmp_path)
    assert row["error_m"] <= 0.05, row


@pytest.mark.parametrize("index", [61, 85])
def test_closed_targets_in_sparse_counts_are_close_or_warned(index, tmp_path):
    """Scenario draws 61 (a box, 8 spots, 1e6 pulses) and 85 (a person, 3 spots, 1e5 pulses),
    0.18 m off with no warning before the held centre's notice (policy.closed.centre_profile):
    the counts' Fisher sds had said a few centimetres."""
    row = _row(index, tmp_path)
    assert row["error_m"] <= 0.15 or row["warned"], row
