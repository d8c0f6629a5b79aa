"""What an input may cost: the memory budget every reader and builder checks before it
allocates anything large (captures, sequences, meshes, scenes, search grids)."""
from __future__ import annotations

from .errors import require


def memory_limit() -> int:
    """Half the memory available now (MemAvailable), or 4 GiB where that is unknown."""
    try:
        with open("/proc/meminfo") as fh:
            kib = next(int(line.split()[1]) for line in fh if line.startswith("MemAvailable:"))
        return kib * 1024 // 2
    except (OSError, StopIteration, ValueError, IndexError):
        return 4 << 30


def require_memory(field: str, n_bytes: float, what: str, fix: str) -> None:
    """Refuse, before allocating, what would not fit in half the memory available now."""
    limit = memory_limit()
    require(n_bytes <= limit, field, f"{what} needs about {n_bytes / 2**30:.3g} GiB, more than "
            f"the {limit / 2**30:.3g} GiB allowed (half the memory available)", fix)
