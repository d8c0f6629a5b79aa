"""MATLAB .mat files (v4-v7, what scipy.io.loadmat reads), with their declared sizes checked
against memory before anything is read."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.errors import InputError, require
from ...core.limits import require_memory


def variables(path) -> dict:
    """{name: (shape, MATLAB class)} as the file declares them, without reading the data."""
    import scipy.io
    path = Path(path)
    require(path.is_file(), f"{path}", "does not exist", "pass the downloaded .mat file")
    try:
        return {name: (tuple(shape), kind) for name, shape, kind in scipy.io.whosmat(path)}
    except NotImplementedError:  # scipy: "Please use HDF reader for matlab v7.3 files"
        raise InputError(f"{path}: is a MATLAB v7.3 (HDF5) file, which scipy.io cannot read. "
                         "Fix: save it again in MATLAB with save(..., '-v7')") from None
    except (ValueError, TypeError, OSError) as exc:
        raise InputError(f"{path}: is not a readable .mat file ({type(exc).__name__}: {exc}). "
                         "Fix: download the file again") from None


def load(path, name: str, ndim: int) -> np.ndarray:
    """One variable as float64, after checking it is declared with `ndim` axes and fits in
    memory (as stored and as float64: 16 bytes a value at most)."""
    import scipy.io
    declared = variables(path)
    require(name in declared, f"{path}: {name}", f"is missing (the file holds "
            f"{sorted(declared)})", "pass the dataset's own, unmodified file")
    shape, kind = declared[name]
    require(len(shape) == ndim and kind in ("double", "single", "uint8", "uint16", "uint32",
                                            "int8", "int16", "int32", "logical"),
            f"{path}: {name}", f"is declared {kind} {shape}, expected a numeric {ndim}-D array",
            "pass the dataset's own, unmodified file")
    require_memory(f"{path}: {name}", 16.0 * float(np.prod(shape, dtype=np.float64)),
                   f"reading {name} {shape}", "crop the file, or read it on a machine with "
                   "more memory")
    value = scipy.io.loadmat(path, variable_names=[name])[name]
    arr = np.asarray(value, dtype=np.float64)
    require(bool(np.all(np.isfinite(arr))), f"{path}: {name}", "contains NaN or inf",
            "pass the dataset's own, unmodified file")
    return arr
