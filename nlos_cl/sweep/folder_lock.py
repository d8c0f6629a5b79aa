"""One sweep at a time in an output folder: an exclusive flock on OUT/.sweep.lock, held from
before the folder's record is read (--resume's runs done) until the summary and plots are
written. Two sweeps writing one folder would both run the runs not yet done and write them
twice into runs.parquet.

A second sweep fails at once rather than waiting: waiting would end in a refusal (the folder
holds a study: --resume needed) or, with --resume, in finding every run done, after however
long the first one takes; and a forgotten sweep would look like a hang. The kernel drops the
lock when its process ends, however it ends, so there is no stale lock to clear. The file is
empty and stays (removing it would let a third sweep lock a fresh file while a second still
holds the old one).
"""
from __future__ import annotations

import os
import stat
from contextlib import contextmanager
from pathlib import Path

from ..core.errors import InputError, require

LOCK_FILE = ".sweep.lock"


@contextmanager
def folder_lock(out: Path):
    """Hold OUT's sweep lock for the `with` block (OUT is created if missing)."""
    try:
        import fcntl
    except ImportError:  # no flock (Windows): one sweep per folder is then the user's care
        yield
        return
    out = Path(out)
    require(not out.exists() or out.is_dir(), f"--out {out}", "is a file, not a folder",
            "pass a folder (it is created if missing)")
    out.mkdir(parents=True, exist_ok=True)
    path = out / LOCK_FILE
    flags = os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
    try:
        fd = os.open(path, flags, 0o644)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot open its lock file {LOCK_FILE} ({exc.strerror})."
                         f" Fix: remove {path} if it is not a plain file, or pick another "
                         "folder") from None
    try:
        require(stat.S_ISREG(os.fstat(fd).st_mode), f"--out {out}", f"{LOCK_FILE} is not a "
                "plain file", f"remove {path}, or pick another folder")
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InputError(f"--out {out}: another nlos-cl sweep is writing this folder now "
                             f"(it holds {LOCK_FILE}). Fix: wait until it ends (then --resume "
                             "adds what is missing), or pick another --out") from None
        except OSError as exc:  # a file system without locks (some network mounts)
            raise InputError(f"--out {out}: cannot lock {LOCK_FILE} ({exc.strerror}), so "
                             "another sweep could write the folder at the same time. Fix: "
                             "pick a folder on a local disk") from None
        yield
    finally:
        os.close(fd)  # closing releases the lock
