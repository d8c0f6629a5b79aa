"""glibc's allocator, kept from handing memory back to the OS between the host model's NumPy
passes (`keep_freed_memory`, called when a host model is built: model.batch, model.host_shapes).

Why: the host model works in arrays of 0.1-10 MB, made and freed dozens of times a frame.
glibc's defaults return the top of the heap to the OS once more than twice the (adaptive) mmap
threshold is free there, so every pass grows the heap again and the kernel zeroes fresh pages:
the deposit of a Jacobian's 5 plates (3 spots x 1,536 points) took 2.0 ms where its arithmetic
takes 0.49 ms (MALLOC_MMAP_THRESHOLD_ / MALLOC_TRIM_THRESHOLD_ set, same process otherwise).

What it costs: freed memory up to TRIM_THRESHOLD_BYTES stays with the process, and arrays
above MMAP_THRESHOLD_BYTES still come from (and go back to) the OS at once, so a process's
extra footprint is bounded by about those sizes. Settings the user made win: nothing is
changed where MALLOC_MMAP_THRESHOLD_ or MALLOC_TRIM_THRESHOLD_ is in the environment, or
NLOS_CL_MALLOPT=0. Elsewhere than glibc (macOS, musl, Windows) it does nothing.
"""
from __future__ import annotations

import ctypes
import os
import sys

M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3  # glibc's mallopt parameters (malloc.h)
MMAP_THRESHOLD_BYTES = 32 * 2 ** 20  # glibc's own upper limit for its adaptive threshold
TRIM_THRESHOLD_BYTES = 64 * 2 ** 20
USER_SETTINGS = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_")

_state: bool | None = None  # None: not tried yet; then whether the settings were applied


def keep_freed_memory() -> bool:
    """Apply the thresholds above once per process (glibc only); whether they are in force."""
    global _state
    if _state is None:
        _state = _apply()
    return _state


def _apply() -> bool:
    if not sys.platform.startswith("linux") or os.environ.get("NLOS_CL_MALLOPT") == "0" \
            or any(name in os.environ for name in USER_SETTINGS):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # not glibc
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES) == 1
                and mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES) == 1)
