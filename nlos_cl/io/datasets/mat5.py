"""What a MATLAB v5 (v6, v7) variable's tags declare, checked before scipy.io reads it: scipy
allocates the byte count a data element's tag declares before reading it (a 1 x 1 array
declaring 3.9 GB took that much), and reads what the tags say into an array of the declared
dims (a complex flag without its imaginary part, or a data type that does not fit, crashed the
process: found by tests/io/test_fuzz_readers.py). A compressed element (v7's
default) is inflated only as far as its first few hundred bytes: the tags sit at its start.

Layout (MathWorks, "MAT-File Format", R2023b, ch. 1): a 128-byte header (text, subsystem
offset, version 0x0100, endian indicator 'IM' or 'MI'), then data elements, each an 8-byte tag
(type, byte count; or a 4-byte small-element tag holding both in its first word) and its data
padded to 8 bytes. A variable is an miMATRIX element holding array flags, dimensions, name and
then the real (and imaginary) part's data element; an miCOMPRESSED element holds one miMATRIX
deflated."""
from __future__ import annotations

import os
import struct
import zlib

from ...core.errors import InputError
from ..safe_write import require_file

MI_MATRIX, MI_COMPRESSED = 14, 15
HEAD_BYTES = 4096  # enough for flags, dims, a name and the data tag


def _tag(buf: bytes, at: int, order: str):
    """(type, byte count, where its data starts, where the next element starts)."""
    word, count = struct.unpack_from(order + "II", buf, at)
    if word >> 16:  # small element: count in the upper half, data in the next 4 bytes
        return word & 0xFFFF, word >> 16, at + 4, at + 8
    return word, count, at + 8, at + 8 + count + (-count % 8)


# miINT8 .. miUINT64 -> bytes a value (MATLAB may store a double array as smaller integers)
MI_SIZES = {1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 6: 4, 7: 4, 9: 8, 12: 8, 13: 8}


def _matrix(body: bytes, order: str):
    """(name, problem or None) of an miMATRIX element's body: for a numeric class, its real
    part's data element must be a number type holding exactly prod(dims) values (scipy reads
    what the tags say into an array of the dims: a mismatch, a complex flag without its
    imaginary part, or an unknown type read past its buffer and crashed the process)."""
    _, _, flags_at, at = _tag(body, 0, order)
    flags = struct.unpack_from(order + "I", body, flags_at)[0]
    _, n_dims, dims_at, at = _tag(body, at, order)
    dims = struct.unpack_from(order + f"{n_dims // 4}i", body, dims_at)
    _, n, name_at, at = _tag(body, at, order)
    name = body[name_at:name_at + n].decode("latin-1")
    if not 6 <= (flags & 0xFF) <= 15:  # not mxDOUBLE_CLASS .. mxUINT64_CLASS: scipy's checks
        return name, None
    if flags & 0x800:
        return name, "holds complex numbers, not real ones"
    kind, count, _, _ = _tag(body, at, order)
    values = 1
    for d in dims:
        values *= max(d, 0)
    if kind not in MI_SIZES:
        return name, f"has a data element of type code {kind}, not a number type"
    if count != values * MI_SIZES[kind]:
        return name, (f"declares {count:,} bytes of data for a {tuple(dims)} array of "
                      f"{MI_SIZES[kind]}-byte values ({values * MI_SIZES[kind]:,} expected)")
    return name, None


def _inflated_head(fh, count: int) -> bytes:
    """The first HEAD_BYTES of a compressed element of `count` bytes, reading no more of it
    than that needs."""
    engine, out, left = zlib.decompressobj(), b"", count
    while len(out) < HEAD_BYTES and left > 0 and not engine.eof:
        chunk = fh.read(min(left, 1 << 16))
        if not chunk:
            break
        left -= len(chunk)
        out += engine.decompress(chunk, HEAD_BYTES - len(out))
    return out


MAX_ELEMENTS = 10_000  # a dataset's .mat holds a few variables; each costs scipy a pass


def _open_v5(path):
    """(file, byte order) of a v5 file opened through the gate, or (None, None) for another
    kind of file (scipy's own checks then apply)."""
    from ...core import gate
    fh = gate.open_regular(path, f"{path}", "pass the downloaded .mat file")
    head = fh.read(128)
    if len(head) < 128 or head[126:128] not in (b"IM", b"MI"):
        fh.close()
        return None, None
    return fh, "<" if head[126:128] == b"IM" else ">"


def check_elements(path) -> None:
    """A v5 file holds at most MAX_ELEMENTS top-level data elements: scipy's whosmat and
    loadmat walk them all, one Python pass each (10^6 one-value variables took minutes)."""
    fh, order = _open_v5(path)
    if fh is None:
        return
    with fh:
        size, at = os.fstat(fh.fileno()).st_size, 128
        for n in range(MAX_ELEMENTS + 1):
            fh.seek(at)
            tag = fh.read(8)
            if len(tag) < 8:
                return
            kind, count = struct.unpack(order + "II", tag)
            at += 8 + count + (0 if kind == MI_COMPRESSED else -count % 8)
            if at >= size:
                return
    raise InputError(f"{path}: holds more than {MAX_ELEMENTS:,} MATLAB variables, far more "
                     "than any dataset's file. Fix: pass the dataset's own file (or save only "
                     "the variables it needs: save(f, 'rect_data', 'width'))")


def variable_problem(path, name: str) -> str | None:
    """What is wrong with variable `name`'s tags (see _matrix), or None where nothing is, the
    file is no v5 file or the variable is not found (scipy's own checks then apply). A name
    held twice is checked in every copy; at most MAX_ELEMENTS elements are walked."""
    require_file(path, f"{path}", "pass the downloaded .mat file")
    check_elements(path)
    fh, order = _open_v5(path)
    if fh is None:
        return None
    with fh:
        at = 128
        while True:
            fh.seek(at)
            tag = fh.read(8)
            if len(tag) < 8:
                return None
            kind, count = struct.unpack(order + "II", tag)
            try:
                if kind == MI_COMPRESSED:
                    inner = _inflated_head(fh, count)
                    found = _matrix(inner[8:], order) if len(inner) >= 8 else (None, None)
                    at += 8 + count
                elif kind == MI_MATRIX:
                    found = _matrix(fh.read(min(count, HEAD_BYTES)), order)
                    at += 8 + count + (-count % 8)
                else:
                    at += 8 + count + (-count % 8)
                    continue
            except (struct.error, zlib.error, UnicodeDecodeError, ValueError):
                return "sits in a file whose tags are damaged (cut short or corrupted)"
            if found[0] == name and found[1] is not None:
                return found[1]
