"""The gate every file read from outside passes before its bytes are parsed: only
regular files are opened (a FIFO blocks the reader, a device never ends), and what a file or
container will expand to (its size, a compressed stream's output, an archive's members) is
checked against a byte budget before it is allocated, whatever the container says of itself.

Readers above this layer (meshes, dataset readers) call `open_regular` for every file they or
the file itself name, and `read_all` for the bytes of a possibly compressed file, with a budget
from `core.limits` scaled by what parsing those bytes costs; `budget` and `too_big` are the one
budget and message every reader uses (HDF5 containers: nlos_cl.io.hdf5_gate, which adds links,
external storage and compressed chunks)."""
from __future__ import annotations

import io
import os
import stat

from .errors import InputError, require

# magic bytes -> container; sniffed from the content, never trusted from the file name
MAGIC = ((b"\x1f\x8b", "gzip"), (b"BZh", "bz2"), (b"\xfd7zXZ\x00", "xz"),
         (b"PK\x03\x04", "zip"), (b"PK\x05\x06", "zip"), (b"(\xb5/\xfd", "zstd"))
TAR_MAGIC_AT_257 = b"ustar"
_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISSOCK, "a socket"))
CHUNK = 1 << 20


def open_regular(path, where: str, fix: str):
    """`path` opened for binary reading, only if it is a regular file (links followed: reading
    through one harms nothing). Opened non-blocking first and checked with fstat, so a FIFO
    swapped in after a stat neither blocks nor is read."""
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0) | \
        getattr(os, "O_NOCTTY", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise InputError(f"{where}: does not exist. Fix: {fix}") from None
    except OSError as exc:
        raise InputError(f"{where}: cannot be read ({exc.strerror}). Fix: {fix}") from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        kind = next((name for test, name in _KINDS if test(mode)), "not a regular file")
        raise InputError(f"{where}: is {kind}, not a regular file (reading it could block or "
                         f"never end). Fix: {fix}")
    return os.fdopen(fd, "rb")


def regular_size(path, where: str, fix: str) -> int:
    """The size in bytes of the regular file `path` (refused otherwise, see open_regular)."""
    with open_regular(path, where, fix) as fh:
        return os.fstat(fh.fileno()).st_size


def container(head: bytes) -> str | None:
    """The compression or archive format `head` (a file's first 512 bytes) starts with."""
    for magic, name in MAGIC:
        if head.startswith(magic):
            return name
    return "tar" if head[257:262] == TAR_MAGIC_AT_257 else None


def budget(max_bytes: int | None = None) -> tuple[int, str]:
    """(bytes a reader may hold, where that number comes from): `max_bytes` where the caller
    passes one, else the memory budget (core.limits.memory_limit)."""
    if max_bytes is not None:
        return int(max_bytes), "max_bytes"
    from .limits import _budget
    return _budget()


def too_big(where: str, limit: int, what: str, fix: str = "", why: str = "") -> InputError:
    """The one message of every reader's budget: what the input declares or expands to, the
    budget and (`why`) where it comes from, and a fix."""
    return InputError(f"{where}: {what} more than the {limit / 2**20:.4g} MiB this reader may "
                      f"hold{f' ({why})' if why else ''}: a decompression bomb, or a file far "
                      f"larger than any this reader expects. Fix: {fix or 'pass a smaller file'}"
                      ", or raise NLOS_CL_MEMORY_LIMIT if it is genuine")



def read_bounded(fh, limit: int, where: str, what: str = "holds") -> bytes:
    """All of the stream `fh`, refused as soon as it passes `limit` bytes (never buffered)."""
    out = bytearray()
    while True:
        block = fh.read(min(CHUNK, limit + 1 - len(out)))
        if not block:
            return bytes(out)
        out += block
        if len(out) > limit:
            raise too_big(where, limit, what)


def _decompressor(kind: str):
    if kind == "gzip":
        import zlib
        return zlib.decompressobj(16 + zlib.MAX_WBITS)
    if kind == "bz2":
        import bz2
        return bz2.BZ2Decompressor()
    import lzma
    return lzma.LZMADecompressor()


def decompress_bounded(raw: bytes, kind: str, limit: int, where: str) -> bytes:
    """A gzip, bz2 or xz stream's output (concatenated streams too), at most `limit` bytes:
    decompressed a block at a time (max_length), so a bomb is refused after `limit` bytes,
    not after it filled memory."""
    require(kind in ("gzip", "bz2", "xz"), where, f"is {kind}-compressed, which this reader "
            "does not open", "decompress it first and pass the plain file")
    out, data = bytearray(), raw
    try:
        while data:  # one compressed stream per pass; pbzip2 and `cat a.gz b.gz` write several
            engine = _decompressor(kind)
            while not engine.eof:
                block = engine.decompress(data, limit + 1 - len(out))
                data = engine.unconsumed_tail if kind == "gzip" else b""
                out += block
                if len(out) > limit:
                    raise too_big(where, limit, "decompresses to")
                if not block and not data and (kind == "gzip" or engine.needs_input):
                    break
            require(engine.eof, where, f"is a {kind} stream cut short (truncated)",
                    "download or copy the whole file again")
            data = engine.unused_data.lstrip(b"\0")  # gzip's trailing zero padding
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - OSError, EOFError, zlib.error, LZMAError
        raise InputError(f"{where}: is a damaged {kind} stream ({type(exc).__name__}: "
                         f"{str(exc)[:120]}). Fix: download or compress the file again") from None
    return bytes(out)


def zip_members(raw: bytes, limit: int, where: str) -> dict[str, bytes]:
    """The regular members of a zip archive {name: bytes}: their declared sizes summed and
    checked against `limit` before any is read, and each read no further than it declared
    (zipfile stops there; a member that lies fails its CRC and is refused)."""
    import zipfile
    try:
        with zipfile.ZipFile(io.BytesIO(raw)) as z:
            infos = [i for i in z.infolist() if not i.is_dir()
                     and not stat.S_ISLNK(i.external_attr >> 16)]
            declared = sum(i.file_size for i in infos)
            if declared > limit:
                raise too_big(where, limit, f"declares {declared / 2**20:.4g} MiB of members,")
            out = {}
            for info in infos:
                with z.open(info) as fh:
                    out[info.filename] = read_bounded(fh, info.file_size, f"{where}: "
                                                      f"{info.filename}", "decompresses to")
            return out
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - BadZipFile, CRC, zlib and NotImplemented alike
        raise InputError(f"{where}: is a damaged or unsupported zip archive "
                         f"({type(exc).__name__}: {str(exc)[:120]}). Fix: pass the plain file, "
                         "or zip it again") from None


def tar_members(raw: bytes, where: str) -> dict[str, bytes]:
    """The regular members of an (already decompressed, so bounded) tar archive; links,
    devices and FIFOs in it are left out."""
    import tarfile
    try:
        with tarfile.open(fileobj=io.BytesIO(raw), mode="r:") as t:
            return {m.name: t.extractfile(m).read() for m in t.getmembers() if m.isreg()}
    except (tarfile.TarError, OSError, AttributeError) as exc:
        raise InputError(f"{where}: is a damaged tar archive ({exc}). Fix: pass the plain "
                         "file") from None


def read_all(path, limit: int, where: str, fix: str) -> tuple[dict[str, bytes], str | None]:
    """({name: bytes}, container) of a regular file whatever wraps it: a plain file as
    {its name: its bytes}, a gzip/bz2/xz file as {its name less the suffix: its output} (a tar
    inside opened too), a zip or tar archive as its regular members. Every size is checked
    against `limit` bytes before it is allocated: the file's own, the stream's output, the
    archive's declared members."""
    from pathlib import Path
    name = Path(path).name
    with open_regular(path, where, fix) as fh:
        size = os.fstat(fh.fileno()).st_size
        if size > limit:
            raise too_big(where, limit, f"is {size / 2**20:.4g} MiB,")
        raw = read_bounded(fh, limit, where, "holds")
    kind = container(raw[:512])
    if kind is None:
        return {name: raw}, None
    if kind == "zip":
        return zip_members(raw, limit, where), kind
    if kind == "tar":
        return tar_members(raw, where), kind
    inner = decompress_bounded(raw, kind, limit, where)
    stem = name.rsplit(".", 1)[0] if "." in name else name
    if container(inner[:512]) == "tar":
        return tar_members(inner, where), f"{kind}+tar"
    return {stem: inner}, kind
