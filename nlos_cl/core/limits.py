"""What an input may cost: the memory budget every reader and builder checks before it
allocates anything large (captures, sequences, meshes, scenes, search grids, the forward
model's buffers), and the caps on counts whose cost is time rather than memory (wall spots,
frames, study runs, fitted targets).

The budget is half the memory available now (MemAvailable), less where the process runs
under an address-space limit (`ulimit -v`: half of what is left of it), or exactly the value
of the environment variable NLOS_CL_MEMORY_LIMIT (bytes, or with a K, M, G or T suffix in
powers of 1024: `NLOS_CL_MEMORY_LIMIT=2G`)."""
from __future__ import annotations

import os
import re

from .errors import InputError, require

MEMORY_LIMIT_ENV = "NLOS_CL_MEMORY_LIMIT"
_UNITS = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}

# Counts refused up front: each costs time (or output) that no memory check sees.
MAX_WALL_SPOTS = 1 << 20  # a 1024 x 1024 SPAD array; LCT's captures have 64^2 .. 256^2
MAX_FRAMES = 1_000_000  # a day at ~12 Hz; each frame is one forward model or one read
MAX_STUDY_RUNS = 10_000_000  # at >= ~0.1 s a run, ~12 days on one core
# Targets of one scene: each is its own forward call and checks (~15 ms on 2 CPU cores), so
# 512 simulate in ~10 s; many small objects are one target as one mesh (trimesh.util.concatenate)
MAX_SCENE_TARGETS = 512
# Fitted targets: each plate is 6 parameters (centre, width, height, yaw), and a histogram
# resolves a few echoes (one per target it sees, separated by more than the pulse and filter
# width), so D histograms determine at most ~2 D plates; past 8 the fit's K^2 Jacobian
# (every plate's 6 columns, each a forward model of all K plates) is minutes per frame and
# the echoes of 8 objects in one scene overlap anyway. ModelEstimator's 'auto' stops at 3.
MAX_TARGETS = 8
TARGETS_PER_HISTOGRAM = 2


def _configured() -> int | None:
    """NLOS_CL_MEMORY_LIMIT in bytes, None if unset; a malformed value is an InputError."""
    text = os.environ.get(MEMORY_LIMIT_ENV, "").strip()
    if not text:
        return None
    match = re.fullmatch(r"(\d+(?:\.\d*)?)\s*([KMGT]?)i?B?", text, re.IGNORECASE)
    if not match or float(match.group(1)) <= 0:
        raise InputError(f"{MEMORY_LIMIT_ENV}: {text!r} is not a memory size. Fix: set it to "
                         "bytes or a size with a K, M, G or T suffix, e.g. 2G, or unset it")
    return int(float(match.group(1)) * _UNITS[match.group(2).upper()])


def _address_space_left() -> int | None:
    """Bytes the address-space limit (ulimit -v, RLIMIT_AS) leaves this process, or None."""
    try:
        import resource
        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft == resource.RLIM_INFINITY:
            return None
        with open("/proc/self/status") as fh:
            used = next(int(line.split()[1]) for line in fh if line.startswith("VmSize:"))
        return max(soft - used * 1024, 0)
    except (ImportError, OSError, StopIteration, ValueError, IndexError):
        return None


def _budget() -> tuple[int, str]:
    """(bytes, where they come from) for memory_limit and its messages."""
    configured = _configured()
    if configured is not None:
        return configured, "set by " + MEMORY_LIMIT_ENV
    try:
        with open("/proc/meminfo") as fh:
            kib = next(int(line.split()[1]) for line in fh if line.startswith("MemAvailable:"))
        limit = kib * 1024 // 2
    except (OSError, StopIteration, ValueError, IndexError):
        limit = 4 << 30
    left = _address_space_left()
    if left is not None and left // 2 < limit:
        return left // 2, "half the address space left under ulimit -v"
    return limit, "half the memory available"


def memory_limit() -> int:
    """The budget in bytes: NLOS_CL_MEMORY_LIMIT if set, else half the memory available now
    (MemAvailable; 4 GiB where that is unknown), at most half the address space left."""
    return _budget()[0]


def require_memory(field: str, n_bytes: float, what: str, fix: str) -> None:
    """Refuse, before allocating, what would not fit in the budget (memory_limit)."""
    limit, why = _budget()
    require(n_bytes <= limit, field, f"{what} needs about {n_bytes / 2**30:.3g} GiB, more than "
            f"the {limit / 2**30:.3g} GiB allowed ({why})", fix)


def require_count(field: str, n, maximum: int, what: str, fix: str) -> int:
    """Refuse a count over `maximum` (before anything is built from it); returns int(n)."""
    require(n <= maximum, field, f"{n:,} {what}, more than the {maximum:,} allowed", fix)
    return int(n)


def require_targets(field: str, k: int, n_histograms: int | None = None) -> None:
    """K fitted targets: at most MAX_TARGETS, and at most TARGETS_PER_HISTOGRAM per histogram
    (what the histograms can determine). For the model estimator before it fits, and the CLI's
    --targets (n_histograms None: the hard cap only)."""
    require_count(field, k, MAX_TARGETS, "targets", f"pass at most {MAX_TARGETS} (or 'auto', "
                  "which tries up to 3)")
    if n_histograms is not None:
        most = TARGETS_PER_HISTOGRAM * n_histograms
        require(k <= most, field, f"{k} targets from {n_histograms} histogram(s): each "
                f"determines at most {TARGETS_PER_HISTOGRAM} echoes, so at most {most} targets",
                f"pass at most {most}, or use a capture with more detector spots")
