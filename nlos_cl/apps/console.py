"""The `nlos-cl` console entry (pyproject's [project.scripts]): cli.main, which returns (tests
and scripts call it in-process), then terminal.leave's quick exit."""
from __future__ import annotations

from .cli import main
from .terminal import leave


def run() -> None:
    leave(main())
