"""What a long computation is doing now, for a person watching it: the library names each
stage as it enters it (`stage("model fit: closed shapes")`, or `with staged(...)` for one that
ends), and the command line's progress line (apps.terminal.Elapsed) shows the latest beside the
seconds. One slot per process, written and read whole (a str), so a reader thread needs no
lock: a line for a person, not a record (the estimator's timings are the record)."""
from __future__ import annotations

from contextlib import contextmanager

_current = ""


def stage(text: str) -> None:
    """Say what the computation is doing from now on ("" for nothing in particular)."""
    global _current
    _current = text


def current() -> str:
    """The stage last said ("" if none)."""
    return _current


@contextmanager
def staged(text: str):
    """`text` while the block runs, then the stage it interrupted."""
    before = _current
    stage(text)
    try:
        yield
    finally:
        stage(before)
