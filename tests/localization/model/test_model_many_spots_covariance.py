"""A frame of many detectors (more than SEARCH_DETECTORS: the fit searches on a spread subset,
then fits every detector once more) takes its covariance from that final fit's last Jacobian
(model.covariance's `reuse`), not from 13 more forward columns; fewer detectors keep the
exact analytic derivatives. The reused covariance is the computed one within the solver's
forward-difference truncation (tests/localization/model/test_model_covariance_reuse.py argues the 6 %). No
timings."""
import warnings

import numpy as np

import nlos_cl as nl
from nlos_cl.core.stats import chi2_quantile
from nlos_cl.core.tuning import SEARCH_DETECTORS
from nlos_cl.localization.model import ModelEstimator, estimator as estimator_module
from nlos_cl.physics import layouts

from conftest import window_around

TRUTH = (2.0, 3.0, 0.0)


def _frame(runtime, spots):
    setup = nl.paper_setup(detector_spots=spots)
    mesh = nl.rectangle(0.3, 1.6, centre=TRUTH, cell_m=0.02)
    axis = window_around(setup, mesh, 10e-12, margin_m=1.0)  # 10 ps bins: a short record
    raw = nl.add_noise(nl.simulate(nl.Scene(setup, nl.Target(mesh), truth=TRUTH), axis,
                                   backend=runtime), 10.0, seed=1)
    return nl.gauss_filter(raw), raw


def _located_with_both(runtime, spots, monkeypatch):
    """(reuse asked, covariance given, covariance computed) of the cold fit's covariance call,
    and the located target."""
    seen = []
    real = estimator_module.covariance

    def spy(problem, result, free, reuse=False):
        got = real(problem, result, free, reuse=reuse)
        seen.append((reuse, got[0], real(problem, result, free)[0]))
        return got
    monkeypatch.setattr(estimator_module, "covariance", spy)
    filtered, raw = _frame(runtime, spots)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        located = nl.locate(filtered, nl.Grid(), raw=raw, estimator=ModelEstimator(),
                            log_mode=True)
    return seen[0], located.targets[0]


def test_many_detectors_reuse_the_final_fits_jacobian(runtime, monkeypatch):
    spots = layouts.spad_patch((-1.0, 0.0, 0.0), (9, 8), (0.05, 0.05))
    assert len(spots) > SEARCH_DETECTORS
    (reuse, got, want), target = _located_with_both(runtime, spots, monkeypatch)
    assert reuse
    assert not np.allclose(got, want, rtol=1e-8)  # the kept Jacobian was used
    sd_got, sd_want = (np.sqrt(np.diag(c)[:3]) for c in (got, want))
    assert np.all(np.isfinite(sd_want))
    assert np.allclose(sd_got, sd_want, rtol=0.06, atol=0), (sd_got, sd_want)
    miss = target.position - np.array(TRUTH)  # a plate's centre: within its 99.9 % ellipsoid
    assert miss @ np.linalg.solve(got[:3, :3], miss) < chi2_quantile(0.999, 3), miss


def test_few_detectors_keep_the_analytic_covariance(runtime, monkeypatch):
    spots = layouts.spad_patch((-1.0, 0.0, 0.0), (4, 3), (0.3, 0.3))
    (reuse, got, want), _ = _located_with_both(runtime, spots, monkeypatch)
    assert not reuse
    assert np.array_equal(got, want, equal_nan=True)
