"""The closed fit's depth profile (policy.closed.depth_profile: four LM fits at held depths) is
run only where its answer is read: for the closed shape chosen, and not where the sanity check
will reject that shape whatever its depth's sd (policy.closed.profiled)."""
from types import SimpleNamespace

import numpy as np
import pytest

from nlos_cl.localization.model.policy import closed, sanity
from nlos_cl.localization.model.shapes import ellipsoid, plate
from nlos_cl.localization.model.solve.records import Covariance, ShapeFit


@pytest.fixture
def cascade(monkeypatch):
    """closed_or_plate with its fits stubbed: a misfit plate, one closed fit of the given BIC
    gain and checks; returns (run(gain, checks, sanity) -> Chosen, the profile's calls)."""
    profiled = []
    plate_problem = SimpleNamespace(obs=SimpleNamespace(), shape=plate)
    shaped = SimpleNamespace(obs=SimpleNamespace(), shape=ellipsoid)
    plate_result = SimpleNamespace(params=np.zeros((1, 6)), cost=1000.0)
    closed_result = SimpleNamespace(params=np.zeros((1, 7)), cost=900.0)
    monkeypatch.setattr(closed, "misfit", lambda *a: (True, 500.0))
    monkeypatch.setattr(closed, "reseat_plate", lambda problem, result, *a: result)
    monkeypatch.setattr(closed, "covariance", lambda *a, **k: Covariance(np.eye(7), {}))
    monkeypatch.setattr(closed, "closed_fits", lambda *a: (
        [ShapeFit(shaped, closed_result, np.ones(7, bool))], False))
    monkeypatch.setattr(closed, "depth_profile", lambda *a: profiled.append(a) or {
        "depth_profile_sd_m": 0.5, "depth_profile": []})

    def run(gain, checks=None, sanity_on=False):
        monkeypatch.setattr(closed, "depth_gain", lambda *a: (gain, 1.0))
        monkeypatch.setattr(sanity, "fit_checks", lambda *a: dict(checks or {}))
        on = {"sanity": True} if sanity_on else {}  # the default: no sanity check
        return closed.closed_or_plate(plate_problem, plate_result, np.ones(6, bool), 30,
                                      Covariance(np.eye(6), {}), **on)
    return run, profiled


def test_a_plate_kept_after_the_closed_fits_costs_no_depth_profile(cascade):
    run, profiled = cascade
    chosen = run(gain=-3.0)
    assert chosen.problem.shape is plate and chosen.cov.info["closed_tried"]
    assert profiled == []  # the old cascade profiled the losing closed fit, then dropped it


def test_a_closed_shape_the_sanity_check_rejects_anyway_is_not_profiled(cascade):
    run, profiled = cascade
    doomed = {"misfit_ratio": 300.0, "explained": 0.8, "depth_unseen": False}
    chosen = run(gain=5.0, checks=doomed, sanity_on=True)
    assert chosen.problem.shape is ellipsoid and profiled == []
    assert "depth_profile_sd_m" not in chosen.cov.info


@pytest.mark.parametrize("checks, sanity_on", [
    ({"misfit_ratio": 300.0, "explained": 0.8}, False),  # no sanity check: the sd is reported
    ({"misfit_ratio": 300.0, "explained": 0.95}, True),  # explained: the depth's sd decides
    ({"misfit_ratio": 50.0, "explained": 0.5}, True),  # explains the data: never rejected
])
def test_a_closed_shape_whose_fate_its_depth_can_change_is_profiled(cascade, checks, sanity_on):
    run, profiled = cascade
    chosen = run(gain=5.0, checks=checks, sanity_on=sanity_on)
    assert len(profiled) == 1 and chosen.cov.info["depth_profile_sd_m"] == 0.5
