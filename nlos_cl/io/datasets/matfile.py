"""MATLAB .mat files, with their declared sizes checked against memory before anything is
read: v4-v7 through scipy.io, v7.3 (an HDF5 file behind a 512-byte header) through h5py, whose
arrays come with MATLAB's axes reversed (they are transposed back here)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.errors import InputError, require
from ...core.limits import require_memory
from ..hdf5_gate import scalar_attribute

HDF5_AT_512 = b"\x89HDF\r\n\x1a\n"  # a v7.3 file's HDF5 signature, after MATLAB's header
NUMERIC = ("double", "single", "uint8", "uint16", "uint32", "int8", "int16", "int32",
           "logical")  # the MATLAB classes read as numbers
FIX = "pass the dataset's own, unmodified file"


def is_v73(path) -> bool:
    with open(path, "rb") as fh:
        head = fh.read(520)
    return head.startswith(b"MATLAB") and head[512:520] == HDF5_AT_512


def _h5_kind(d) -> str:
    """A v7.3 dataset's MATLAB class as `variables` reports it: 'sparse' for MATLAB's sparse
    storage (a group, or MATLAB_sparse), 'complex' for a compound dtype (MATLAB's complex
    numbers, or anything else with fields), else its MATLAB_class."""
    kind = str(scalar_attribute(d, "MATLAB_class", f"{d.file.filename}: {d.name}", FIX,
                                "double"))  # none: plain numbers
    if "MATLAB_sparse" in d.attrs:
        return "sparse"
    if d.dtype.fields is not None or d.dtype.kind not in "fiub":
        return "complex" if d.dtype.fields is not None else f"{kind} stored as {d.dtype}"
    return kind


def _h5_shape(d) -> tuple:
    """MATLAB's shape of a v7.3 dataset: its axes reversed; an empty array (MATLAB_empty) is
    stored as its dimensions, so those are read (a few numbers) instead."""
    if scalar_attribute(d, "MATLAB_empty", f"{d.file.filename}: {d.name}", FIX, 0):
        dims = np.asarray(d[()]).ravel() if d.size <= 32 else np.zeros(2)
        return tuple(int(v) for v in dims) if dims.size else (0, 0)
    return tuple(d.shape)[::-1]


def _h5_variables(path) -> dict:
    """A v7.3 file's numeric arrays (datasets or sparse groups with a MATLAB_class), shapes in
    MATLAB's order; links and external storage are refused first (they would read other
    files)."""
    import h5py

    from ..ytal.checks import unreadable
    from ..ytal.fields import check_storage
    try:
        with h5py.File(path, "r") as f:
            check_storage(f, path, "MATLAB file")
            out = {}
            for name, d in f.items():
                if "MATLAB_class" not in d.attrs:
                    continue
                if isinstance(d, h5py.Dataset) and d.shape is not None:
                    out[name] = (_h5_shape(d), _h5_kind(d))
                elif isinstance(d, h5py.Group):
                    out[name] = ((), "sparse" if "MATLAB_sparse" in d.attrs else "struct")
            return out
    except (OSError, RuntimeError) as exc:
        raise unreadable(exc, path, what="MATLAB file") from None


def h5_array(f, name: str, path) -> np.ndarray:
    """A v7.3 variable as float64 in MATLAB's axis order (h5py reverses them: transposed
    back), after its storage (numeric, not sparse or complex) and size are checked."""
    import h5py

    from ..ytal.checks import unreadable
    d = f.get(name)
    require(isinstance(d, h5py.Dataset), f"{path}: {name}", f"is missing or not an array "
            f"(the file holds {sorted(f)[:10]})", "pass the dataset's own, unmodified file")
    kind, shape = _h5_kind(d), _h5_shape(d)
    require(kind in NUMERIC, f"{path}: {name}", f"is stored as {kind} {shape}, not real "
            "numbers", "pass the dataset's own, unmodified file")
    require_memory(f"{path}: {name}", 16.0 * float(np.prod(shape, dtype=np.float64)),
                   f"reading {name} {shape}", "read it on a machine with more memory")
    if scalar_attribute(d, "MATLAB_empty", f"{path}: {name}", FIX, 0):
        return np.zeros(shape)
    from ...core import gate
    from ..hdf5_gate import check_chunks
    held = float(np.prod(shape, dtype=np.float64)) * d.dtype.itemsize
    # what each compressed chunk may expand to, as every capture's chunks (a deflate chunk
    # inflates to the end of its stream, whatever size it declares)
    check_chunks(d, f"{path}: {name}", gate.budget(None)[0] - 3 * held, held,
                 "pass the dataset's own, unmodified file")
    try:
        return np.asarray(d[()], dtype=np.float64).T  # MATLAB's axis order again
    except (OSError, RuntimeError, ValueError, TypeError) as exc:
        raise unreadable(exc, path, name, "MATLAB file", d) from None


def variables(path) -> dict:
    """{name: (shape, MATLAB class)} as the file declares them, without reading the data."""
    import scipy.io

    from ..safe_write import require_file
    path = Path(path)
    require_file(path, f"{path}", "pass the downloaded .mat file")
    if is_v73(path):
        return _h5_variables(path)
    from .mat5 import check_elements
    check_elements(path)  # before scipy walks every element
    try:
        return {name: (tuple(shape), kind) for name, shape, kind in scipy.io.whosmat(path)}
    except NotImplementedError:  # scipy: "Please use HDF reader for matlab v7.3 files"
        raise InputError(f"{path}: is a MATLAB v7.3 (HDF5) file whose header nlos_cl does not "
                         "recognise. Fix: save it again in MATLAB with save(..., '-v7')") from None
    except Exception as exc:  # noqa: BLE001 - ValueError, zlib.error, struct.error...: damaged
        raise InputError(f"{path}: is not a readable .mat file ({type(exc).__name__}: "
                         f"{' '.join(str(exc).split())[:120]}). Fix: download the file again"
                         ) from None


def load(path, name: str, ndim: int) -> np.ndarray:
    """One variable as float64, after checking it is declared with `ndim` axes and fits in
    memory (as stored and as float64: 16 bytes a value at most)."""
    declared = variables(path)
    require(name in declared, f"{path}: {name}", f"is missing (the file holds "
            f"{sorted(declared)[:10]})", "pass the dataset's own, unmodified file")
    shape, kind = declared[name]
    require(len(shape) == ndim and kind in NUMERIC,
            f"{path}: {name}", f"is declared {kind} {shape}, expected a numeric {ndim}-D array",
            "pass the dataset's own, unmodified file")
    require_memory(f"{path}: {name}", 16.0 * float(np.prod(shape, dtype=np.float64)),
                   f"reading {name} {shape}", "crop the file, or read it on a machine with "
                   "more memory")
    if is_v73(path):
        import h5py

        from ..ytal.checks import unreadable
        try:
            f = h5py.File(path, "r")
        except (OSError, RuntimeError) as exc:
            raise unreadable(exc, path, what="MATLAB file") from None
        with f:
            arr = h5_array(f, name, path)
    else:
        arr = _v5_array(path, name, shape)
    require(bool(np.all(np.isfinite(arr))), f"{path}: {name}", "contains NaN or inf",
            "pass the dataset's own, unmodified file")
    return arr


def _v5_array(path, name: str, shape: tuple) -> np.ndarray:
    """A v4-v7 variable through scipy.io, after its tags are checked (mat5.variable_problem:
    the data element must hold exactly its dims' values, so scipy allocates no more and reads
    no past its buffer); a complex array is refused (its imaginary part would be dropped), and
    a damaged element is an InputError."""
    import scipy.io

    from .mat5 import variable_problem
    problem = variable_problem(path, name)
    require(problem is None, f"{path}: {name}", f"{problem}", "pass the dataset's own, "
            "unmodified file")
    try:
        arr = scipy.io.loadmat(path, variable_names=[name])[name]
    except (ValueError, TypeError, OSError, EOFError, IndexError, KeyError) as exc:
        raise InputError(f"{path}: {name}: cannot be read, the file is damaged "
                         f"({type(exc).__name__}: {str(exc)[:120]}). Fix: download the file "
                         "again") from None
    except Exception as exc:  # noqa: BLE001 - zlib.error from a damaged compressed element
        raise InputError(f"{path}: {name}: cannot be read, the file is damaged "
                         f"({type(exc).__name__}). Fix: download the file again") from None
    kind = getattr(arr, "dtype", np.dtype(object)).kind
    require(isinstance(arr, np.ndarray) and kind in "fiub", f"{path}: {name}",
            f"holds {'complex numbers' if kind == 'c' else type(arr).__name__ + ' data'}, not "
            "real numbers", "pass the dataset's own, unmodified file")
    return np.asarray(arr, dtype=np.float64)
