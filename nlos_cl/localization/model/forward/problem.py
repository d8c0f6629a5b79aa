"""What the solvers and the policy read of a forward problem (`ForwardProblem`), declared: the
device's `likelihood.Problem`, the host's plates (`batch.HostProblem`) and closed shapes
(`host_shapes.HostShapeProblem`) all provide it, and mypy checks that they do (`_provided`,
pyproject's [tool.mypy] files). A stub in a test provides the same members."""
from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from .batch import HostProblem
from .host_shapes import HostShapeProblem
from .likelihood import Problem


class ForwardProblem(Protocol):
    obs: Any  # forward.data.Observation: the samples, their noise, spots and laser, the axes
    backend: Any  # where the device's forward operation runs (None: host models only)
    shape: Any  # the target's Shape module (shapes.shape.Shape)
    lattice: Any  # the plates' cells, a pair or a shapes.plate.Lattice
    calls: int  # forward calls made for it (the estimator's timings)
    model_s: float  # their time
    shadows: bool  # K >= 2 targets shadow each other in its model (solve.fit's stepped columns)
    batched: bool  # column_batch evaluates its rows in one call (solve.fit speculates)
    plates_on_host: bool  # plates on the host: coarser lattices, analytic derivatives, probes
    closed_on_host: bool  # its closed shapes' problems run on the host too

    def column(self, p) -> np.ndarray: ...

    def columns(self, params) -> np.ndarray: ...

    def column_batch(self, rows, like=None, occluders=None) -> np.ndarray: ...

    def occluders(self, params) -> list | None: ...

    def linear(self, cols, warm=None) -> np.ndarray: ...

    def mean(self, cols, lin) -> np.ndarray: ...

    def residual(self, cols, lin) -> np.ndarray: ...

    def null_cost(self) -> float: ...


def _provided(device: Problem, plates: HostProblem, closed: HostShapeProblem
              ) -> list[ForwardProblem]:
    """Never called: mypy checks here that each problem provides the protocol."""
    return [device, plates, closed]
