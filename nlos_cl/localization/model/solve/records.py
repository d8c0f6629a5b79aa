"""The records the model's stages hand each other, typed (instead of positional tuples):
a covariance with what it found (`Covariance`), one shape fitted on a problem (`ShapeFit`),
that fit with its covariance, as the plate-or-closed choice returns it (`Chosen`), and the
whole frame's fit as the estimator reports it (`Fitted`). The NamedTuples still unpack as the
tuples they replace."""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from .fit import FitResult

if TYPE_CHECKING:  # (a type only: the records load no forward model)
    from ..forward.problem import ForwardProblem


class Covariance(NamedTuple):
    """covariance()'s answer: every parameter's covariance (free and linear) and its info
    (Birge ratio, what the checks found: reported in the fit's details)."""
    matrix: np.ndarray
    info: dict


class ShapeFit(NamedTuple):
    """One shape's fit: the problem of that shape, the result, the free mask."""
    problem: "ForwardProblem"
    result: FitResult
    free: np.ndarray


class Chosen(NamedTuple):
    """A fit with its covariance: the plate, or the closed shape chosen for the target."""
    problem: "ForwardProblem"
    result: FitResult
    free: np.ndarray
    cov: Covariance


@dataclass
class Fitted:
    """A frame's fit: `problem` (the plates' Problem, which counts every forward call made for
    the frame), the chosen fit (`chosen`: a closed shape's problem where one was chosen, and its
    result, free mask and covariance) and the short fits' history."""
    problem: "ForwardProblem"
    chosen: Chosen
    history: list

    @property
    def result(self) -> FitResult:
        return self.chosen.result


class SubsetChoice(NamedTuple):
    """The plate-or-closed choice made on a spread subset of many detectors (policy.subset):
    the subset's problem and the fit chosen there."""
    problem: "ForwardProblem"
    chosen: Chosen
