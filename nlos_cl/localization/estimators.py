"""The estimator registry: names ('paper', 'mean', 'model') to estimators, and the default.

The default (`as_estimator(None)`) is the model fit (localization.model, loaded on first use)."""
from __future__ import annotations

from ..core.errors import InputError
from .paper import PaperArgmax
from .posterior import PosteriorMean


def _model_estimator():
    from .model import ModelEstimator  # loaded only when asked for (a one-shot locate's start-up)
    return ModelEstimator()


ESTIMATORS = {"paper": PaperArgmax, "mean": PosteriorMean, "model": _model_estimator}


# The default (issue 11): the most accurate estimator within the time budget, the model fit.
DEFAULT_ESTIMATOR = "model"


def as_estimator(value):
    """A name ('paper', 'mean', 'model'), an object with estimate(scored), or None: the default."""
    if value is None:
        value = DEFAULT_ESTIMATOR
    if isinstance(value, str):
        if value not in ESTIMATORS:
            raise InputError(f"estimator: unknown name {value!r}. Fix: pass one of "
                             f"{sorted(ESTIMATORS)} or an object with estimate(scored)")
        return ESTIMATORS[value]()
    if not hasattr(value, "estimate"):
        raise InputError(f"estimator: expected a name or an object with estimate(scored), got "
                         f"{type(value).__name__}. Fix: pass e.g. 'paper'")
    return value
