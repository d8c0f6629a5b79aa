"""The input gate (nlos_cl.core.gate) for HDF5 containers: y-tal captures, sequences and MATLAB
v7.3 files pass it before any field is read.

- only regular files are opened (core.gate.open_regular's rule);
- every link in the file is data stored in it: external links, soft links, external raw
  storage and virtual datasets (which read other files: /etc/passwd as H) are refused wherever
  they sit in the tree, before any field is looked up (links resolve on lookup);
- what the reader will hold is checked against the memory budget before it is allocated: the
  declared sizes of the datasets it reads (a leading-axis slice of those it reads a row at a
  time), a variable-length value at most the file bytes no fixed-size dataset stores (it lives
  in the file's heap), each chunk's buffer, and what a compressed chunk can expand to: HDF5's
  deflate filter inflates a chunk to its stream's end whatever the chunk declares (a 400 kB
  file whose one 8 kB chunk inflates to 400 MB took 440 MB to read), so a chunk that could
  pass the budget is inflated here first, bounded, and refused if it holds more than declared.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core import gate
from ..core.errors import InputError, require

MAX_LINKS = 100_000  # a capture holds ~15 fields, a MATLAB file a few hundred objects
# What one stored byte of a chunk can become: deflate's format caps at 1032:1; LZF's longest
# back-reference (264 bytes in 3) at 88:1. Filters that keep the size (shuffle, fletcher32,
# nbit, scale-offset, szip) decode into the chunk's own buffer.
EXPANSION = {1: 1032, 32000: 88}
KEEPS_SIZE = {2, 3, 4, 5, 6}


@dataclass(frozen=True)
class Read:
    """A dataset a reader will hold: `extra` bytes a value beyond its stored type (H read as
    float64 beside its stored slice: 8), `rows`: the leading-axis rows held at a time (None:
    all of it; a sequence holds one frame)."""

    extra: int = 0
    rows: int | None = None


def open_file(path, where: str, fix: str, what: str = "file"):
    """h5py.File of `path` (read-only), only if it is a regular file; an HDF5 library error
    (a lock, a file it cannot open) becomes unreadable()'s one line."""
    import h5py
    gate.regular_size(path, where, fix)
    try:
        return h5py.File(path, "r")
    except (OSError, RuntimeError, ValueError) as exc:
        raise unreadable(exc, path, what=what) from None


def check_links(f, where: str, what: str = "file") -> None:
    """Every link under f is a hard link to an object stored in the file, and every dataset's
    raw data is in the file (no external storage, no virtual mapping): checked on the whole
    tree before any field is read, at most MAX_LINKS links."""
    import h5py
    seen = []
    try:  # nothing raised inside the visit: h5py turns that into a SystemError
        f.visititems_links(lambda name, link: seen.append((name, link))
                           or (len(seen) > MAX_LINKS or None))
    except (OSError, RuntimeError, KeyError, ValueError, SystemError) as exc:
        raise unreadable(exc, f.filename, what=what) from None
    require(len(seen) <= MAX_LINKS, where, f"holds more than {MAX_LINKS:,} HDF5 objects, far "
            f"more than any {what} holds", f"pass the {what} itself")
    for name, link in seen:
        kind = ("an external link (to another file)" if isinstance(link, h5py.ExternalLink)
                else "a soft link" if isinstance(link, h5py.SoftLink)
                else None if isinstance(link, h5py.HardLink) else "a user-defined link")
        require(kind is None, f"{where}: {name}", f"is {kind}, not data stored in the {what}",
                f"write the field's data into the {what} itself (h5py: copy it)")
    check_attributes(f, where, what, [name for name, _ in seen])
    for name, _ in seen:
        try:
            obj = f.get(name)
            plist = obj.id.get_create_plist() if isinstance(obj, h5py.Dataset) else None
            external = plist is not None and plist.get_external_count() > 0
            virtual = plist is not None and plist.get_layout() == h5py.h5d.VIRTUAL
        except (OSError, RuntimeError, KeyError, ValueError) as exc:
            raise unreadable(exc, f.filename, name, what) from None
        kind = ("external raw storage (its bytes are read from other files)" if external
                else "a virtual dataset (mapped from other files)" if virtual else None)
        require(kind is None, f"{where}: {name}", f"uses {kind}; nlos_cl reads only data "
                f"stored in the {what} itself", "write the data into the file (h5py: "
                "f.create_dataset(name, data=...)), or convert it with y-tal")


def check_attributes(f, where: str, what: str, names: list[str]) -> None:
    """Every object's attributes (the root's too), by their declared sizes, never their values:
    at most MAX_LINKS of them, and their bytes within the memory budget (a reader that reads an
    attribute holds all of it; a variable-length one lives in the file's heap, at most the
    file's size)."""
    import h5py
    limit, why = gate.budget(None)
    count, held, heap = 0, 0.0, 0.0
    for name in ["/", *names]:
        try:
            oid = f[name].id
            n = h5py.h5a.get_num_attrs(oid)
            count += n
            require(count <= MAX_LINKS, where, f"holds more than {MAX_LINKS:,} HDF5 "
                    f"attributes, far more than any {what} holds", f"pass the {what} itself")
            for i in range(n):
                a = h5py.h5a.open(oid, index=i)
                values = float(np.prod(a.shape or (), dtype=np.float64))
                if a.dtype.kind == "O" or a.get_type().get_class() == h5py.h5t.VLEN:
                    heap = float(Path(f.filename).stat().st_size)
                    held += 16.0 * values
                else:
                    held += values * a.dtype.itemsize
        except InputError:
            raise
        except (OSError, RuntimeError, KeyError, ValueError, TypeError) as exc:
            raise unreadable(exc, f.filename, name, what) from None
    if held + heap > limit:
        raise gate.too_big(where, limit, f"declares {(held + heap) / 2**20:.4g} MiB of HDF5 "
                           "attributes,", f"pass the {what} itself, without the added "
                           "attributes", why)


def scalar_attribute(obj, name: str, where: str, fix: str, default=None):
    """Attribute `name` of obj as one value (bytes decoded as Latin-1), `default` where it is
    absent; read only when it declares exactly one value, so an attribute of 10^6 numbers
    under a name a reader expects to be a word is refused, never read."""
    if name not in obj.attrs:
        return default
    try:
        shape = obj.attrs.get_id(name).shape or ()
    except (OSError, RuntimeError, KeyError, ValueError) as exc:
        raise unreadable(exc, obj.file.filename, f"{obj.name} attribute {name}") from None
    require(int(np.prod(shape, dtype=np.float64)) == 1, f"{where}: attribute {name}",
            f"holds {shape} values, not one", fix)
    try:
        value = np.asarray(obj.attrs[name]).ravel()[0]
    except (OSError, RuntimeError, KeyError, ValueError, TypeError) as exc:
        raise unreadable(exc, obj.file.filename, f"{obj.name} attribute {name}") from None
    return value.decode("latin-1") if isinstance(value, bytes) else value


def _values(d, rows) -> float:
    shape = tuple(d.shape or ())
    if rows is not None and shape:
        shape = (min(rows, shape[0]),) + shape[1:]
    return float(np.prod(shape, dtype=np.float64))


def _variable(d) -> bool:
    import h5py
    return d.dtype.kind == "O" and h5py.check_ref_dtype(d.dtype) is None


def _names(f) -> list[str]:
    """Every object's name under f (check_links has capped their count)."""
    out = []
    try:
        f.visit(out.append)
    except SystemError as exc:  # h5py's wrapping of an error inside the visit
        raise RuntimeError(str(exc)) from None
    return out


def _heap_room(f) -> float:
    """Bytes of the file no fixed-size dataset stores: where a variable-length value lives."""
    import h5py
    stored = []
    for name in _names(f):
        o = f.get(name)
        if isinstance(o, h5py.Dataset) and not _variable(o):
            stored.append(o.id.get_storage_size())
    return max(float(Path(f.filename).stat().st_size) - sum(stored), 0.0)


def check_budget(f, where: str, reads: dict, max_bytes: int | None = None, fix: str = ""
                 ) -> float:
    """The bytes the datasets `reads` ({name: Read}) will take, checked against the budget
    (core.gate.budget(max_bytes)) before any is read, then each one's chunks (check_chunks)
    against what the budget has left; returns that need."""
    import h5py
    limit, why = gate.budget(max_bytes)
    sets = {k: f[k] for k in reads if isinstance(f.get(k), h5py.Dataset)}
    room = _heap_room(f) if any(_variable(d) for d in sets.values()) else 0.0
    cost = {k: _values(d, reads[k].rows) * ((room if _variable(d) else d.dtype.itemsize)
                                             + reads[k].extra) for k, d in sets.items()}
    need = sum(cost.values())
    if need > limit:
        big = max(cost, key=cost.get)
        d = sets[big]
        held = "" if reads[big].rows is None else f", {reads[big].rows} row(s) at a time"
        raise gate.too_big(f"{where}: {big}", limit, f"declares {need / 2**20:.4g} MiB of data "
                           f"to hold ({big} {d.shape} {d.dtype}{held}),", fix, why)
    for k, d in sets.items():
        check_chunks(d, f"{where}: {k}", limit - need, _values(d, reads[k].rows)
                     * d.dtype.itemsize, fix)
    return need


def _pipeline(d) -> list[int]:
    plist = d.id.get_create_plist()
    return [plist.get_filter(i)[0] for i in range(plist.get_nfilters())]


def check_chunks(d, where: str, room: float, held: float = 0.0, fix: str = "") -> None:
    """A chunked dataset's chunk buffer beyond the `held` bytes read from it (a chunk may
    declare more than the dataset holds), and what each compressed chunk can expand to, within
    `room` bytes; a deflate chunk that could pass it is inflated here (bounded) and refused if
    it holds more than its declared size. Two expanding filters in one pipeline (nested
    compression, which no writer produces) are refused, and so is a filter whose expansion
    the gate cannot bound (a plugin: blosc, zstd, bitshuffle, ...; h5py may decode it where
    hdf5plugin is imported, and its output has no bound the gate knows)."""
    if d.chunks is None:
        return
    chunk_bytes = float(np.prod(d.chunks, dtype=np.float64)) * d.dtype.itemsize
    if chunk_bytes - held > room:
        raise gate.too_big(where, int(room), f"declares chunks of {chunk_bytes / 2**20:.4g} MiB "
                           f"({d.chunks}),", fix)
    filters = _pipeline(d)
    expanding = [(i, fid) for i, fid in enumerate(filters) if fid not in KEEPS_SIZE]
    require(len(expanding) <= 1, where, f"is compressed twice over (HDF5 filters {filters})",
            "write it with one compression filter (h5repack -f GZIP=4 IN OUT)")
    if not expanding:
        return
    index, fid = expanding[0]
    if fid not in EXPANSION:
        named = _filters(d) or "a plugin"
        raise InputError(f"{where}: is compressed with HDF5 filter {fid} ({named}), whose "
                         "output nlos_cl cannot bound before decoding it (a decompression bomb "
                         "would fill memory). Fix: rewrite it with gzip or no compression "
                         "(h5repack -f GZIP=4 IN OUT)")
    for info in _chunks(d):
        if info.filter_mask & (1 << index) or info.size * EXPANSION[fid] <= room:
            continue  # stored raw, or it cannot expand past the budget
        if fid != 1 or info.size > room:
            raise gate.too_big(where, int(room), f"holds a {info.size / 2**20:.4g} MiB "
                               f"compressed chunk at {info.chunk_offset} that may expand to "
                               f"{info.size * EXPANSION[fid] / 2**20:.4g} MiB,", fix)
        _, raw = d.id.read_direct_chunk(info.chunk_offset)
        _inflate(raw, int(chunk_bytes), f"{where}: chunk at {info.chunk_offset}")


def _chunks(d):
    out = []
    try:
        d.id.chunk_iter(out.append)
    except (AttributeError, RuntimeError):  # an HDF5 without H5Dchunk_iter
        out = [d.id.get_chunk_info(i) for i in range(d.id.get_num_chunks())]
    return out


def _inflate(raw: bytes, declared: int, where: str) -> None:
    engine = zlib.decompressobj()
    try:
        out = engine.decompress(raw, declared + 1)
    except zlib.error as exc:
        raise InputError(f"{where}: is a damaged compressed chunk ({exc}). Fix: copy or write "
                         "the file again") from None
    require(len(out) <= declared, where, f"inflates to more than the {declared:,} bytes its "
            "chunk declares (a decompression bomb)", "write the file again (h5py, y-tal)")


def _filters(dataset) -> str:
    """The names of a dataset's compression filters ('' when unknown)."""
    try:
        plist = dataset.id.get_create_plist()
        return ", ".join(plist.get_filter(i)[3].decode("ascii", "replace")
                         for i in range(plist.get_nfilters()))
    except Exception:  # noqa: BLE001 - a name for a message; none is fine
        return ""


def unreadable(exc: BaseException, path, field: str | None = None, what: str = "capture",
               dataset=None) -> InputError:
    """The InputError for an exception h5py raised while opening `path` or reading `field`
    (`dataset`: the h5py.Dataset it was reading, to name its compression filters)."""
    where = f"{what} {path}" + (f": {field}" if field else "")
    text = " ".join(str(exc).split())
    low = text.lower()
    filters = _filters(dataset)
    if isinstance(exc, BlockingIOError) or "unable to lock file" in low:
        return InputError(f"{where}: is locked: another program has it open for writing "
                          "(HDF5 file locking). Fix: let that program finish or close the "
                          "file; to read it while it is written anyway, set "
                          "HDF5_USE_FILE_LOCKING=FALSE")
    # HDF5 looks for a filter it lacks in its plugin directory, and says only that it is gone
    if ("filter" in low and ("not registered" in low or "not available" in low)) or \
            "can't open directory" in low or "plugin" in low:
        return InputError(f"{where}: is compressed with an HDF5 filter this h5py does not have "
                          f"({filters or text[:200]}). Fix: pip install hdf5plugin (then import "
                          "hdf5plugin before reading), or rewrite it with gzip or no "
                          "compression (h5repack -f GZIP=4 IN OUT)")
    if "external" in low and "link" in low:
        return InputError(f"{where}: is an external link to another file ({text[:200]}). Fix: "
                          "copy the linked data into the file itself")
    return InputError(f"{where}: cannot be read, the file is incomplete or corrupted "
                      f"({type(exc).__name__}: {text[:300]}). Fix: copy or write the {what} "
                      "again")
