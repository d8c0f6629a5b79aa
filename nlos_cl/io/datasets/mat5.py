"""What a MATLAB v5 (v6, v7) variable's data element declares, read from its tags alone: scipy.io
allocates the byte count a data element's tag declares before reading it, so that count is
checked (matfile._v5_array) before scipy is asked for the array. A compressed element (v7's
default) is inflated only as far as its first few hundred bytes: the tags sit at its start.

Layout (MathWorks, "MAT-File Format", R2023b, ch. 1): a 128-byte header (text, subsystem
offset, version 0x0100, endian indicator 'IM' or 'MI'), then data elements, each an 8-byte tag
(type, byte count; or a 4-byte small-element tag holding both in its first word) and its data
padded to 8 bytes. A variable is an miMATRIX element holding array flags, dimensions, name and
then the real (and imaginary) part's data element; an miCOMPRESSED element holds one miMATRIX
deflated."""
from __future__ import annotations

import struct
import zlib

from ..safe_write import require_file

MI_MATRIX, MI_COMPRESSED = 14, 15
HEAD_BYTES = 4096  # enough for flags, dims, a name and the data tag


def _tag(buf: bytes, at: int, order: str):
    """(type, byte count, where its data starts, where the next element starts)."""
    word, count = struct.unpack_from(order + "II", buf, at)
    if word >> 16:  # small element: count in the upper half, data in the next 4 bytes
        return word & 0xFFFF, word >> 16, at + 4, at + 8
    return word, count, at + 8, at + 8 + count + (-count % 8)


def _matrix(body: bytes, order: str):
    """(name, byte count of the real part's data) from an miMATRIX element's body; None for a
    class without one (cell, struct, sparse, char...)."""
    _, _, flags_at, at = _tag(body, 0, order)
    flags = struct.unpack_from(order + "I", body, flags_at)[0]
    _, _, _, at = _tag(body, at, order)  # dimensions
    _, n, name_at, at = _tag(body, at, order)
    name = body[name_at:name_at + n].decode("latin-1")
    if not 6 <= (flags & 0xFF) <= 15:  # mxDOUBLE_CLASS .. mxUINT64_CLASS
        return name, None
    return name, _tag(body, at, order)[1]


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


def declared_data_bytes(path, name: str) -> int | None:
    """The byte count variable `name`'s real-part data element declares, or None where the file
    is no v5 file, the variable is not found, or its class carries no such element (scipy's own
    checks then apply)."""
    require_file(path, f"{path}", "pass the downloaded .mat file")
    with open(path, "rb") as fh:
        head = fh.read(128)
        if len(head) < 128 or head[126:128] not in (b"IM", b"MI"):
            return None
        order = "<" if head[126:128] == b"IM" else ">"
        at, best = 128, None
        while True:
            fh.seek(at)
            tag = fh.read(8)
            if len(tag) < 8:
                return best
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
            except (struct.error, zlib.error, UnicodeDecodeError):
                return best  # damaged: scipy's reading says so
            if found[0] == name and found[1] is not None:  # a name twice: the larger counts
                best = max(best or 0, found[1])
