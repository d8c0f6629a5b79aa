"""What a y-tal field may hold, checked where it enters. What went wrong when HDF5 could not read
one (a lock, a missing compression filter and a cut-off file each get their own fix, rather
than all being called "corrupted") is the input gate's: nlos_cl.io.hdf5_gate.unreadable."""
from __future__ import annotations

import copy
import functools

import numpy as np

from ...core.errors import InputError, require, shown
from ..hdf5_gate import unreadable  # noqa: F401  (the one wording, for the readers here)

MAX_WALL_SPAN_M = 50.0  # a relay wall's scanned spots span metres; 1000x that is millimetres
MAX_BIN_M = 1.5  # delta_t: 1.5 m of optical path is a 5 ns bin; 1000x a ps bin is millimetres
_TRUE, _FALSE = {"true", "1"}, {"false", "0"}


def flag(value, field: str, path, what: str = "capture") -> bool:
    """An HDF5 boolean as tools store it: a bool or 0/1, or text "true"/"false"/"0"/"1" in any
    case ("False" is a non-empty string, so bool() would call it True)."""
    arr = np.ravel(np.asarray(value))
    item = arr[0] if arr.size == 1 else None
    if isinstance(item, (bytes, np.bytes_)):
        item = bytes(item).decode("utf-8", "replace")
    if isinstance(item, str) and item.strip().lower() in _TRUE | _FALSE:
        return item.strip().lower() in _TRUE
    ok = item is not None and not isinstance(item, str) and (
        isinstance(item, (bool, np.bool_)) or (np.issubdtype(arr.dtype, np.number)
                                               and float(item) in (0.0, 1.0)))
    require(ok, f"{what} {path}: {field}", f"expected a boolean, got {shown(value)}",
            "store True/False (or 1/0, or the text true/false)")
    return bool(item)


def check_wall_scale(points, field: str, path) -> None:
    """Wall points (file frame) spread over more than MAX_WALL_SPAN_M: millimetres, likely."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    span = float(np.ptp(pts, axis=0).max()) if len(pts) else 0.0
    require(span <= MAX_WALL_SPAN_M, f"capture {path}: {field}", f"its points span {span:.4g} m "
            f"of wall, more than the {MAX_WALL_SPAN_M:g} m a relay wall scan covers: that looks "
            "like millimetres", "store coordinates in metres (divide by 1000)")


def check_bin(delta_t: float, path) -> None:
    require(delta_t <= MAX_BIN_M, f"capture {path}: delta_t", f"is {delta_t:.4g} m of optical "
            f"path per bin (a {delta_t / 0.299792458:.3g} ns bin): that looks like millimetres",
            "store delta_t and t_start in metres (divide by 1000)")


def our_metadata(info, path=""):
    """scene_info's `nlos_cl` mapping, or None. Another tool's scene_info (not YAML, not UTF-8)
    simply holds none of ours; one that breaks the YAML reader's bounds (an alias bomb, deep
    nesting, a key twice: nlos_cl.io.yamlfile) is refused, not expanded."""
    from ..yamlfile import MAX_BYTES, YamlLimit, load_json_yaml
    if isinstance(info, bytes):
        try:
            info = info.decode("utf-8-sig")
        except UnicodeDecodeError:
            return None
    if not isinstance(info, str) or len(info) > 16 * MAX_BYTES:  # far beyond what we write
        return None
    parsed = load_json_yaml(info)  # what nlos_cl writes: JSON, read without importing PyYAML
    if parsed is not None:
        return parsed.get("nlos_cl")  # parsed afresh: nothing shared to copy
    else:
        import yaml
        try:
            parsed = _parsed(info)
        except YamlLimit as exc:
            raise InputError(f"capture {path}: scene_info: {exc.problem}. Fix: {exc.fix}"
                             ) from None
        except yaml.YAMLError:
            return None
    return copy.deepcopy(parsed.get("nlos_cl")) if isinstance(parsed, dict) else None


@functools.lru_cache(maxsize=4)
def _parsed(text: str):
    """scene_info parsed once per text (read_sequence reads it twice; the consumer sensor's
    walk carries 47 kB, ~0.2 s for PyYAML's Python reader, which the bounds need); callers get
    deep copies of it."""
    import yaml

    from ..yamlfile import yaml_loader
    return yaml.load(text, Loader=yaml_loader())  # a SafeLoader subclass
