"""Many detectors (model.subset): what is decided on the spread subset. The fits are stubs
here (their numbers are other tests'): this checks the flow, i.e. that a closed shape the
sanity check will reject on the choice's subset (CHOICE_DETECTORS spread detectors) ends the
fit there (nothing fitted on every detector), and that a choice made before the final fit is
reused, not made twice. The real case
(CC-SOCR's scan read as one laser: 4,096 points 113 -> 10 s, the same answer) is in
tests/realdata/test_realdata_ccsocr.py's reach only where ../shared is present."""
from types import SimpleNamespace

import numpy as np
import pytest

from nlos_cl.core.tuning import (
    CHOICE_DETECTORS,
    FINISH_NFEV,
    MAX_EXTENT_M,
    MISFIT_BIRGE,
    SEARCH_DETECTORS,
)
from nlos_cl.localization.model.forward.data import Observation
from nlos_cl.localization.model.policy import subset
from nlos_cl.localization.model.shapes import box, plate
from nlos_cl.localization.model.solve.records import Chosen, Covariance


def _obs(n_det):
    rng = np.random.default_rng(n_det)
    spots = np.column_stack([rng.uniform(-1, 1, n_det), np.zeros(n_det),
                             rng.uniform(-0.5, 0.5, n_det)])
    y = rng.poisson(3.0, (n_det, 50)).astype(float)
    return Observation("poisson", spots, np.zeros(3), np.zeros(n_det), np.full(n_det, 0.01), y,
                       np.ones(y.shape, bool), 0.01, np.ones(n_det), np.eye(1, 50)[0],
                       np.zeros(n_det))


class _Problem:
    def __init__(self, obs, shape=plate, null=1e12):
        self.obs, self.shape, self.calls, self.model_s = obs, shape, 0, 0.0
        self.backend, self.closed_on_host, self.lattice = None, True, (16, 32)
        self.null = null  # the no-target cost: by default the fits explain all but ~1e-6

    def null_cost(self):
        return self.null


def _result(n_params, cost):
    return SimpleNamespace(params=np.zeros((1, n_params)), cost=cost, n_residuals=1000,
                           linear=np.ones(1), jacobian=None)


@pytest.fixture
def stubs(monkeypatch):
    """The fits replaced: fit_targets gives a plate of deviance 400 per dof (a misfit) on the
    subset; closed_or_plate a box (misfit 400, depth sd `depth_sd`); `fit` records where it
    runs."""
    calls = {"fit_on": [], "choices": 0, "depth_sd": 0.5}
    plate_fit = _result(plate.N_PARAMS, 400.0 * 993)

    def fit_targets(search, est, argmax, free, held):
        return plate_fit, ["search"]

    def closed_or_plate(search, rough, free, nfev, cov, closed, tried=False, smooth=None,
                        sanity=False, beyond=False):
        calls["choices"] += 1
        calls["sanity"] = sanity
        calls["tried"] = tried
        result = _result(box.N_PARAMS, 400.0 * 992)
        cov_box = np.zeros((box.N_PARAMS, box.N_PARAMS))
        cov_box[box.DEPTH, box.DEPTH] = calls["depth_sd"] ** 2
        return Chosen(_Problem(search.obs, box), result, np.ones(box.N_PARAMS, bool),
                      Covariance(cov_box, {}))

    def fit(problem, params, free, nfev, **kw):
        calls["fit_on"].append(len(problem.obs.spots))
        calls.setdefault("nfev", []).append(nfev)
        return _result(np.shape(params)[-1], 1.0 * 993)

    monkeypatch.setattr("nlos_cl.localization.model.policy.select.fit_targets", fit_targets)
    monkeypatch.setattr(subset, "closed_or_plate", closed_or_plate)
    monkeypatch.setattr(subset, "fit", fit)
    monkeypatch.setattr(subset, "covariance",
                        lambda problem, result, free: Covariance(None, {}))
    monkeypatch.setattr("nlos_cl.localization.model.forward.host_shapes.shape_problem",
                        lambda problem, shape: _Problem(problem.obs, shape))
    return calls


def _est(sanity=True):
    return SimpleNamespace(closed="auto", sanity=sanity, final_nfev=30,
                           problem=lambda obs, backend: _Problem(obs))


def test_a_doomed_closed_shape_on_the_subset_ends_the_fit(stubs):
    problem = _Problem(_obs(4 * SEARCH_DETECTORS))
    free = np.ones(plate.N_PARAMS, bool)
    result, _, choice = subset.cold_fit(_est(), problem, np.zeros(3), free, None)
    # the plate refitted on the choice's spread detectors, nothing on every detector
    assert result is None and stubs["fit_on"] == [CHOICE_DETECTORS] and stubs["choices"] == 1
    chosen, _, _, (_, info) = choice[1]
    assert chosen.shape is box and info["subset_detectors"] == CHOICE_DETECTORS
    assert subset.doomed(*choice[1])
    assert stubs["sanity"] is True  # the choice may skip what only a kept fit reads


def test_a_closed_shape_whose_depth_is_seen_is_refitted_on_every_detector(stubs):
    """Depth sd 0.01 m: the box is not doomed; the final plate fit runs on all detectors, and
    plate_or_closed reuses the subset's choice (no second choice) to refit the box on all."""
    stubs["depth_sd"] = 0.01
    n_det = 4 * SEARCH_DETECTORS
    problem = _Problem(_obs(n_det))
    free = np.ones(plate.N_PARAMS, bool)
    result, _, choice = subset.cold_fit(_est(), problem, np.zeros(3), free, None)
    assert result is not None and stubs["fit_on"] == [CHOICE_DETECTORS, n_det]
    # every detector's fit finishes from the subset's answer: FINISH_NFEV evaluations at most
    assert stubs["nfev"][-1] == FINISH_NFEV < _est().final_nfev
    misfit_plate = _result(plate.N_PARAMS, 400.0 * 993)  # the final plate misses them too
    chosen, _, _, _ = subset.plate_or_closed(_est(), problem, misfit_plate, free,
                                                 Covariance(None, {}), choice)
    assert chosen.shape is box and stubs["choices"] == 1
    assert stubs["fit_on"] == [CHOICE_DETECTORS, n_det, n_det]
    # the box too finishes from the subset's fit (LCT: ~100 s in 30 evaluations before)
    assert stubs["nfev"][-1] == FINISH_NFEV


def test_without_the_sanity_check_nothing_ends_on_the_subset(stubs):
    problem = _Problem(_obs(2 * SEARCH_DETECTORS))
    free = np.ones(plate.N_PARAMS, bool)
    result, _, choice = subset.cold_fit(_est(sanity=False), problem, np.zeros(3), free, None)
    assert result is not None and choice is not None


def test_doomed_reads_the_sanity_checks_conditions():
    """Misfit AND (depth unseen OR less than EXPLAINED_MIN of the signal explained)."""
    obs = _obs(8)
    cov = np.zeros((box.N_PARAMS, box.N_PARAMS))
    for ratio, sd, unexplained, want in [(400, 0.5, 1e-6, True), (400, 0.01, 1e-6, False),
                                         (2, 0.5, 1e-6, False), (400, 0.01, 0.2, True),
                                         (2, 0.01, 0.2, False)]:
        cov[box.DEPTH, box.DEPTH] = sd ** 2
        result = _result(box.N_PARAMS, ratio * (1000 - box.N_PARAMS - 1))
        free = np.ones(box.N_PARAMS, bool)
        problem = _Problem(obs, box, null=result.cost / unexplained)
        assert subset.doomed(problem, result, free, Covariance(cov, {})) is want
        assert ratio > MISFIT_BIRGE or not want
    assert not subset.doomed(_Problem(obs, plate), _result(plate.N_PARAMS, 4e5),
                             np.ones(plate.N_PARAMS, bool), Covariance(cov, {}))



@pytest.mark.parametrize("n_det, on_subset", [(CHOICE_DETECTORS, False),
                                              (2 * CHOICE_DETECTORS, True)])
def test_the_choice_is_made_on_a_subset_above_choice_detectors(stubs, n_det, on_subset):
    """Up to CHOICE_DETECTORS the closed shapes are fitted on every detector; above, on that
    many spread ones, and a doomed choice (misfit 400, depth sd 0.5 m) is not refitted on all."""
    problem = _Problem(_obs(n_det))
    misfit_plate = _result(plate.N_PARAMS, 400.0 * 993)
    chosen, _, _, (_, info) = subset.plate_or_closed(_est(), problem, misfit_plate,
                                                     np.ones(plate.N_PARAMS, bool),
                                                     Covariance(None, {}))
    assert chosen.shape is box and stubs["choices"] == 1
    assert len(chosen.obs.spots) == (CHOICE_DETECTORS if on_subset else n_det)
    assert stubs["fit_on"] == ([CHOICE_DETECTORS] if on_subset else [])
    assert ("subset_detectors" in info) is on_subset


@pytest.mark.parametrize("box_better", [False, True])
def test_an_adequate_plate_on_many_detectors_tries_closed_shapes_only_on_the_subset(
        stubs, monkeypatch, box_better):
    """A plate that fits (deviance ~1 per dof) on 6 x CHOICE_DETECTORS detectors: the depth
    probe runs on every detector; where it says a box behind would do better the closed
    shapes are fitted on the subset (tried: whatever the subset's own plate does), not on
    all; where it does not, the plate stands and nothing more is fitted."""
    probed = []

    def box_behind(problem, result, cov):
        probed.append(len(problem.obs.spots))
        cov[1].update(box_probe_better=box_better)
        return box_better
    monkeypatch.setattr(subset, "box_behind", box_behind)
    n_det = 6 * CHOICE_DETECTORS
    problem = _Problem(_obs(n_det))
    adequate = _result(plate.N_PARAMS, 1.0 * 993)
    chosen, _, _, (_, info) = subset.plate_or_closed(_est(), problem, adequate,
                                                     np.ones(plate.N_PARAMS, bool),
                                                     Covariance(None, {}))
    assert probed == [n_det]
    if box_better:
        assert stubs["choices"] == 1 and stubs["tried"] is True
        assert stubs["fit_on"][0] == CHOICE_DETECTORS and chosen.shape is box
    else:
        assert stubs["choices"] == 0 and stubs["fit_on"] == [] and chosen is problem
        assert info["box_probe_better"] is False and info["closed_tried"] is False


def test_a_closed_shape_larger_than_any_target_is_doomed_whatever_its_fit():
    """sanity.doubt rejects a target larger than MAX_EXTENT_M before any other test, so a
    subset's closed shape that size is not refitted on every detector (LCT's SU scan: a 3 m
    cylinder refitted on 4,096 spots, then rejected); a plate that size is not a closed
    shape's question, and a closed shape under it still reads the misfit conditions."""
    obs = _obs(8)
    cov = np.zeros((box.N_PARAMS, box.N_PARAMS))
    cov[box.DEPTH, box.DEPTH] = 0.01 ** 2  # depth seen
    free = np.ones(box.N_PARAMS, bool)
    for height, want in [(MAX_EXTENT_M + 0.1, True), (MAX_EXTENT_M - 0.1, False)]:
        result = _result(box.N_PARAMS, 2.0 * (1000 - box.N_PARAMS - 1))  # explains the data
        result.params[0, 3:6] = (0.3, height, 0.3)
        problem = _Problem(obs, box, null=result.cost / 1e-6)
        assert subset.doomed(problem, result, free, Covariance(cov, {})) is want
