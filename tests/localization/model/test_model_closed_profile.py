"""What the closed shapes' cascade (policy.closed.closed_or_plate) spends only where its answer
can be read: the closed fit's depth and centre profiles (LM fits at held depths and held
centres) for the closed shape chosen, and not where the sanity check will reject that shape
whatever its depth's sd (`profiled`); the closed search itself not where the plate's misfit
and unexplained signal rule out any closed shape being reported (`beyond_closed`)."""
from types import SimpleNamespace

import numpy as np
import pytest

from nlos_cl.localization.model.policy import closed, depth, sanity
from nlos_cl.localization.model.shapes import ellipsoid, plate
from nlos_cl.localization.model.solve.records import Covariance, ShapeFit


@pytest.fixture
def cascade(monkeypatch):
    """closed_or_plate with its fits stubbed: a misfit plate, one closed fit of the given BIC
    gain and checks; returns (run(gain, checks, sanity) -> Chosen, the profile's calls)."""
    profiled, searched, plate_fit = [], [], {"birge": 500.0, "left": 0.05}
    plate_problem = SimpleNamespace(obs=SimpleNamespace(), shape=plate,
                                    null_cost=lambda: 1000.0 / plate_fit["left"])
    shaped = SimpleNamespace(obs=SimpleNamespace(mode="poisson"), shape=ellipsoid)
    plate_result = SimpleNamespace(params=np.zeros((1, 6)), cost=1000.0)
    closed_result = SimpleNamespace(params=np.zeros((1, 7)), cost=900.0)
    monkeypatch.setattr(closed, "misfit", lambda *a: (True, plate_fit["birge"]))
    monkeypatch.setattr(closed, "reseat_plate", lambda problem, result, *a: result)
    monkeypatch.setattr(closed, "covariance", lambda *a, **k: Covariance(np.eye(7), {}))
    monkeypatch.setattr(closed, "closed_fits", lambda *a: searched.append(a) or (
        [ShapeFit(shaped, closed_result, np.ones(7, bool))], False))
    monkeypatch.setattr(closed, "depth_profile", lambda *a: profiled.append(a) or {
        "depth_profile_sd_m": 0.5, "depth_profile": []})
    monkeypatch.setattr(closed, "centre_profile", lambda *a: profiled.append(a) or [])

    def run(gain, checks=None, sanity_on=False, beyond=True):
        monkeypatch.setattr(closed, "depth_gain", lambda *a: (gain, 1.0))
        monkeypatch.setattr(sanity, "fit_checks", lambda *a: dict(checks or {}))
        on = {"sanity": True} if sanity_on else {}  # the default: no sanity check
        on["beyond"] = beyond  # model.subset passes it for few detectors
        return closed.closed_or_plate(plate_problem, plate_result, np.ones(6, bool), 30,
                                      Covariance(np.eye(6), {}), **on)
    run.plate_fit, run.searched, run.shaped = plate_fit, searched, shaped
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
    assert len(profiled) == 2 and chosen.cov.info["depth_profile_sd_m"] == 0.5  # depth, centre
    assert chosen.cov.info["centre_rivals"] == []  # counts: the centre profiled too
    run.shaped.obs.mode = "gauss"
    chosen = run(gain=5.0, checks=checks, sanity_on=sanity_on)
    assert len(profiled) == 3 and "centre_rivals" not in chosen.cov.info


def test_a_plate_that_leaves_more_than_any_reported_closed_shape_may_skips_the_closed_search(
        cascade):
    """CC-SOCR's "4" as one laser: the plate's misfit 420-480, 25-34 % of the signal left;
    closed shapes were fitted for 2-4 s and then lost to the plate or were rejected."""
    run, _ = cascade
    run.plate_fit.update(birge=450.0, left=0.3)
    chosen = run(gain=5.0, sanity_on=True)
    assert run.searched == [] and chosen.problem.shape is plate
    assert chosen.cov.info["closed_skipped_left"] == pytest.approx(0.3)
    note = depth.unseen_note(plate, None, None, chosen.cov.info)
    assert note.startswith("the depth of target 1 was not found") and "30 %" in note


@pytest.mark.parametrize("birge, left, sanity_on, beyond", [
    (450.0, 0.3, False, True),  # no sanity check: a closed shape is reported whatever it left
    (450.0, 0.05, True, True),  # a bright closed target's plate: its closed fit may explain it
    (50.0, 0.5, True, True),  # a closed fit may bring the misfit under MISFIT_BIRGE
    (450.0, 0.3, True, False),  # many detectors: the subset's doomed fit ends it cheaper
])
def test_a_closed_shape_that_could_be_reported_is_searched(cascade, birge, left, sanity_on,
                                                           beyond):
    run, _ = cascade
    run.plate_fit.update(birge=birge, left=left)
    chosen = run(gain=5.0, checks={"misfit_ratio": 1.0, "explained": 1.0}, sanity_on=sanity_on,
                 beyond=beyond)
    assert len(run.searched) == 1 and chosen.problem.shape is ellipsoid
