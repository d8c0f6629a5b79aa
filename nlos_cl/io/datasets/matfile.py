"""MATLAB .mat files, with their declared sizes checked against memory before anything is
read: v4-v7 through scipy.io, v7.3 (an HDF5 file behind a 512-byte header) through h5py, whose
arrays come with MATLAB's axes reversed (they are transposed back here)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.errors import InputError, require
from ...core.limits import require_memory


HDF5_AT_512 = b"\x89HDF\r\n\x1a\n"  # a v7.3 file's HDF5 signature, after MATLAB's header
NUMERIC = ("double", "single", "uint8", "uint16", "uint32", "int8", "int16", "int32",
           "logical")  # the MATLAB classes read as numbers


def is_v73(path) -> bool:
    with open(path, "rb") as fh:
        head = fh.read(520)
    return head.startswith(b"MATLAB") and head[512:520] == HDF5_AT_512


def _h5_variables(path) -> dict:
    """A v7.3 file's numeric arrays (datasets with a MATLAB_class), shapes in MATLAB's order;
    links and external storage are refused first (they would read other files)."""
    import h5py

    from ..ytal.checks import unreadable
    from ..ytal.fields import check_storage
    try:
        with h5py.File(path, "r") as f:
            check_storage(f, path, "MATLAB file")
            out = {}
            for name, d in f.items():
                kind = d.attrs.get("MATLAB_class") if isinstance(d, h5py.Dataset) else None
                if kind is not None and d.shape is not None:
                    out[name] = (tuple(d.shape)[::-1], np.asarray(kind).item().decode())
            return out
    except (OSError, RuntimeError) as exc:
        raise unreadable(exc, path, what="MATLAB v7.3 file") from None


def variables(path) -> dict:
    """{name: (shape, MATLAB class)} as the file declares them, without reading the data."""
    import scipy.io

    from ..safe_write import require_file
    path = Path(path)
    require_file(path, f"{path}", "pass the downloaded .mat file")
    if is_v73(path):
        return _h5_variables(path)
    try:
        return {name: (tuple(shape), kind) for name, shape, kind in scipy.io.whosmat(path)}
    except NotImplementedError:  # scipy: "Please use HDF reader for matlab v7.3 files"
        raise InputError(f"{path}: is a MATLAB v7.3 (HDF5) file whose header nlos_cl does not "
                         "recognise. Fix: save it again in MATLAB with save(..., '-v7')") from None
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
    require(len(shape) == ndim and kind in NUMERIC,
            f"{path}: {name}", f"is declared {kind} {shape}, expected a numeric {ndim}-D array",
            "pass the dataset's own, unmodified file")
    require_memory(f"{path}: {name}", 16.0 * float(np.prod(shape, dtype=np.float64)),
                   f"reading {name} {shape}", "crop the file, or read it on a machine with "
                   "more memory")
    if is_v73(path):
        import h5py
        with h5py.File(path, "r") as f:
            arr = np.asarray(f[name][()], dtype=np.float64).T  # MATLAB's axis order again
    else:
        arr = np.asarray(scipy.io.loadmat(path, variable_names=[name])[name], dtype=np.float64)
    require(bool(np.all(np.isfinite(arr))), f"{path}: {name}", "contains NaN or inf",
            "pass the dataset's own, unmodified file")
    return arr
