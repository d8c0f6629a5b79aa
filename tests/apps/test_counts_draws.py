"""Photon-count draws (`nlos-cl reproduce draws --only counts`) whose closed fit was 0.2-0.44 m
off with sds of 1-5 cm and no warning, re-run alone as the page runs them: the held-centre
profile (policy.closed.centre_profile) says that a centre 0.15 m away explains the data nearly
as well; draws answered within 2 cm stay without that notice (the rule's other side)."""
import warnings

import pytest

from nlos_cl.apps.reproduce.draws.experiment import rerun

# the page's rows keep each warning's first clause (run._short): the centre's notice and the
# sd's (depth.UNCERTAIN_WARNING) share it; neither was said on these draws before
CENTRE_NOTICE = "the position of target 1 is poorly determined"


def _row(index):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rows = rerun("counts", index, 2201)
    return next(r for r in rows if r["estimator"] == "default")


@pytest.mark.parametrize("index", [26, 190])
def test_a_closed_fit_far_off_on_sparse_counts_is_warned(index):
    """Draw 26: a cylinder (491 signal photons, 3 spots) fitted as an ellipsoid 0.44 m off,
    Laplace sds 0.013-0.047 m; draw 190: a sphere (378 photons, 6 spots) 0.23 m off."""
    row = _row(index)
    assert row["error_m"] <= 0.15 or CENTRE_NOTICE in row["warnings"], row


@pytest.mark.parametrize("index", [14, 17])
def test_a_closed_fit_the_counts_pin_down_has_no_centre_notice(index):
    row = _row(index)
    assert row["error_m"] <= 0.05 and CENTRE_NOTICE not in row["warnings"], row
