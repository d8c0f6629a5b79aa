"""`nlos-cl bench`: every registered operation against its NumPy twin and against this device's
own limits, then the pipeline and a frame stream. See harness.py for how things are timed."""
from __future__ import annotations

from pathlib import Path

from .cases import Row, all_rows
from .report import report


def run(device=None, smoke=False, out_dir: Path | None = None, say=print, force=False) -> str:
    """Bench, then report; `force` lets out_dir's files replace ones nlos_cl did not write."""
    from ...ops.opencl_backend import get_runtime
    rt = get_runtime(device)
    rows = all_rows(rt, smoke, say)
    from .model_paths import table
    return report(rt.name, rows, smoke, out_dir, force, paths=table(rt, smoke, say))


__all__ = ["Row", "all_rows", "report", "run"]
