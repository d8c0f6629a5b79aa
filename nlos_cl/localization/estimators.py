"""The estimator registry: names ('paper', 'mean', 'model') to estimators, and the one policy
that chooses an estimator for a capture (`choose_estimator`: locate_capture, the Tracker built
by track_sequence, and the CLI through both).

The default (`as_estimator(None)`) is the model fit (localization.model, loaded on first use)."""
from __future__ import annotations

from typing import Callable, Mapping

from ..core.errors import InputError, require, spelled
from .estimate import Estimator
from .paper import PaperArgmax
from .posterior import PosteriorMean


def _model_estimator() -> Estimator:
    from .model import ModelEstimator  # loaded only when asked for (a one-shot locate's start-up)
    return ModelEstimator()


ESTIMATORS: dict[str, Callable[[], Estimator]] = {"paper": PaperArgmax, "mean": PosteriorMean, "model": _model_estimator}


# The default: the most accurate estimator within the time budget, the model fit.
DEFAULT_ESTIMATOR = "model"


def as_estimator(value) -> Estimator:
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


def estimator_names() -> list[str]:
    """The registered names, sorted: what the CLI's --estimator and studies accept."""
    return sorted(ESTIMATORS)


# What the default says where it is not the model fit (paired and confocal captures).
PAIRED_LOCATE_NOTE = ("paired and confocal captures are located with the paper's argmax by "
                      "default (the model fit is checked on simulations only); pass "
                      "estimator='model' to fit")
PAIRED_TRACK_NOTES = {
    "mean": "paired and confocal captures are tracked with the mean and covariance of the "
            "paper's likelihood by default (the model fit is checked on simulations only); "
            "pass --estimator model to fit",
    "paper": "paired and confocal captures are tracked with the paper's argmax by default "
             "with several targets (the model fit is checked on simulations only); pass "
             "--estimator model to fit"}
CHOICE_NAMES = {"estimator": "estimator", "reflectance": "reflectance", "targets": "targets"}


def choose_estimator(estimator=None, *, targets=1, reflectance=None, paired: bool = False,
                     tracking: bool = False, names: Mapping[str, str] = CHOICE_NAMES
                     ) -> tuple[Estimator, str | None]:
    """(estimator object, note or None): `estimator` as given (a name or an object), or by
    default the model fit with `targets` targets and `reflectance`, except for a paired or
    confocal capture (`paired`) without a reflectance: the paper's argmax when locating, and
    when tracking the mean of the paper's likelihood (one target; on the consumer sensor's walk
    the track's median step 0.0254 -> 0.0182 m) or its argmax (several); `note` says so.
    A reflectance is the model fit's; when tracking, the mean gives one position a frame, so
    it is refused with several targets (`nlos-cl locate` has always taken it and reports it).
    `names`: how errors name the options (the CLI passes its flags)."""
    note = None
    if estimator is None and paired and reflectance is None:
        estimator = ("mean" if targets in (1, "auto") else "paper") if tracking else "paper"
        note = PAIRED_TRACK_NOTES[estimator] if tracking else PAIRED_LOCATE_NOTE
    if tracking and isinstance(estimator, str) and estimator != "model":
        flag = names["estimator"]
        require(estimator != "mean" or targets in (1, "auto"), flag, "mean gives one position "
                "a frame, "
                "the likelihood's mean over the region, which lies between two targets",
                f"pass {spelled(flag, 'paper')} or model with {names['targets']} above 1")
    if reflectance is not None:
        require(estimator in (None, "model"), names["reflectance"], "is for the model fit; the "
                "paper's likelihood has no reflectance", f"leave out "
                f"{spelled(names['estimator'], estimator)}, or {names['reflectance']}")
    if estimator is None or (isinstance(estimator, str) and estimator == "model"):
        from .model import ModelEstimator  # loaded only when chosen (a one-shot locate's start-up)
        return ModelEstimator(targets=targets, reflectance=reflectance), note
    return as_estimator(estimator), note
