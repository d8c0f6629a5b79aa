"""The Tracker's options in groups (tracking.options) and the model estimator's
(model.options): an option passed by its old flat name is refused with one line naming its
group and how to pass it; `grouped` turns a config's flat names into the groups."""
import pytest

import nlos_cl as nl
from nlos_cl.localization.model import FitBudget, Instrument, ModelEstimator
from nlos_cl.tracking import MeasurementNoise, SearchPlan, Tracker, TrackRules, grouped

from test_tracking_kalman import _layout


@pytest.mark.parametrize("name, arg, group", [
    ("fallback_sigma_m", "noise", "MeasurementNoise"),
    ("max_birge_ratio", "noise", "MeasurementNoise"),
    ("max_misses", "rules", "TrackRules"), ("confirm", "rules", "TrackRules"),
    ("warm_start", "plan", "SearchPlan"), ("log_mode", "plan", "SearchPlan")])
def test_an_old_tracker_option_names_its_group(name, arg, group):
    with pytest.raises(nl.InputError, match=rf"^Tracker\.{name}: is an option of {group} now "
                       rf".*Fix: pass {arg}={group}\({name}=\.\.\.\)"):
        Tracker(_layout(), estimator="paper", **{name: 1})
    with pytest.raises(nl.InputError, match=r"^Tracker\.colour: is not an option"):
        Tracker(_layout(), estimator="paper", colour="red")


def test_grouped_options_reach_the_tracker():
    t = Tracker(_layout(), estimator="paper", **grouped(max_misses=7, max_birge_ratio=2.0,
                                                         gated_search=False))
    assert t.lifecycle.max_misses == 7 and t.max_birge_ratio == 2.0 and not t.gated_search
    assert grouped(warm_start=False) == {"plan": SearchPlan(warm_start=False)}
    assert grouped(min_sigma_m=0.01, confirm=(3, 4)) == {
        "noise": MeasurementNoise(min_sigma_m=0.01), "rules": TrackRules(confirm=(3, 4))}
    with pytest.raises(nl.InputError, match=r"^tracker\.speed: is not a tracker option"):
        grouped(speed=1.0)


def test_the_model_estimators_groups():
    est = ModelEstimator(instrument=Instrument(pulse_fwhm_s=35e-12, jitter_s=10e-12),
                         budget=FitBudget(final_nfev=40, warm_nfev=5))
    assert est.pulse_sigma_s == pytest.approx(35e-12 / 2.3548, rel=1e-4)
    assert (est.jitter_s, est.final_nfev, est.warm_nfev) == (10e-12, 40, 5)
    assert ModelEstimator().warm_nfev == 10 and ModelEstimator().final_nfev == 30
    for name, arg, group in (("pulse_fwhm_s", "instrument", "Instrument"),
                             ("warm_nfev", "budget", "FitBudget")):
        with pytest.raises(nl.InputError, match=rf"^ModelEstimator\.{name}: is an option of "
                           rf"{group} now.*Fix: pass {arg}={group}\({name}=\.\.\.\)"):
            ModelEstimator(**{name: 1})
