"""Files we write appear whole or not at all, and never replace a file nlos_cl did not write
unless asked: the atomic write every writer of the package uses (captures, sequences, tables,
figures)."""
from __future__ import annotations

import os
import secrets
from pathlib import Path

from ..core.errors import InputError, require


def require_writable(path, *, keep_unless=None, force: bool = False, what: str = "file",
                     kind: str = "a file of this kind") -> None:
    """What atomic_write checks before it writes, for callers that check before any work: the
    folder exists, the path is not a folder, and an existing file for which keep_unless(path)
    is False is replaced only with force=True."""
    path = Path(path)
    where = f"{what} {path}"
    require(path.parent.is_dir(), where, f"the folder {path.parent} does not exist",
            "create the folder first, or pick another path")
    require(not path.is_dir(), where, "is a folder", "pass a file path")
    if path.exists() and not force and keep_unless is not None:
        require(keep_unless(path), where, f"exists and is not {kind}, so writing would destroy "
                "it", "pick another path, or pass force=True (nlos-cl: --force) to replace it")


def atomic_write(path, write, *, keep_unless=None, force: bool = False, what: str = "file",
                 kind: str = "a file of this kind") -> Path:
    """Call write(tmp) on a temporary file beside `path`, fsync it, then os.replace it onto
    `path`: Ctrl-C, a crash or a full disk leave the old file as it was (a SIGKILL can leave a
    hidden '.NAME.*.tmp' beside it, never a broken NAME). An existing file for which
    keep_unless(path) is False is replaced only with force=True. Concurrent writers: the
    target's identity (inode, size, mtime, mode) is noted first and checked again under an
    exclusive flock on the folder just before the rename; a writer that finds it changed
    refuses with an InputError (its own result not saved, the other writer's kept), so no
    result is ever lost without notice. The old file's permissions carry over."""
    path = Path(path)
    where = f"{what} {path}"
    require_writable(path, keep_unless=keep_unless, force=force, what=what, kind=kind)
    before = _identity(path)
    tmp = None
    try:
        while tmp is None:  # the name is bound before the file exists (see _create)
            tmp = str(path.parent / f".{path.name}.{secrets.token_hex(8)}.tmp")
            if not _create(tmp):
                tmp = None  # taken (another writer's): never ours to remove
        write(tmp)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        mask = os.umask(0o022)
        os.umask(mask)
        os.chmod(tmp, before[-1] if before else 0o666 & ~mask)
        _replace(tmp, path, before, where)
        tmp = None
    except OSError as exc:
        raise InputError(f"{where}: could not be written ({exc}); any existing file there is "
                         "unchanged. Fix: pick a writable folder with free space")
    finally:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
    return path


def _create(tmp: str) -> bool:
    """Create the empty temporary `tmp` (False if the name is taken). atomic_write binds the
    name first: with tempfile.mkstemp a Ctrl-C landing after the file was made but before its
    name was bound left the file behind (seen once in CI under repeated SIGINT)."""
    try:
        os.close(os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
    except FileExistsError:
        return False
    return True


def _identity(path: Path):
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return None
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_mode & 0o7777)


def _replace(tmp: str, path: Path, before, where: str) -> None:
    import fcntl
    dirfd = os.open(path.parent, os.O_RDONLY)
    try:
        fcntl.flock(dirfd, fcntl.LOCK_EX)
        if _identity(path) != before:
            raise InputError(f"{where}: was {'created' if before is None else 'replaced'} by "
                             "another writer while this one was writing; that file was kept and "
                             "this result was NOT saved. Fix: write to another path, or run "
                             "again to replace it")
        os.replace(tmp, path)
        os.fsync(dirfd)
    finally:
        os.close(dirfd)  # also releases the lock
