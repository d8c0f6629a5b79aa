"""Built OpenCL programs kept on disk as the device's own binaries, so that a new process loads
a program instead of asking the compiler for it.

Why: pyopencl leaves caching to the OpenCL implementation where it has its own cache (PoCL,
NVIDIA), but PoCL's cache still runs clang's preprocessor on every build to find its entry:
~20 ms a program even for a one-line kernel, ~90 ms of a one-shot `nlos-cl locate` for its
four programs. Loading the binary PoCL gave us costs 2-10 ms
(docs/results/performance/performance.md, one-shot).

A binary is keyed by everything that shapes it: the source text (includes already inlined),
the build options and the device, platform and driver versions. A binary the implementation
refuses (a driver update under the same version string) is rebuilt from source and replaced.
Best effort throughout: a folder that cannot be read or written only means building from source.
"""
from __future__ import annotations

import os
import tempfile
import time
import warnings
from pathlib import Path

from .devices import cl

try:  # hashlib's blake2b itself, without hashlib's OpenSSL import (~2.5 ms a process)
    from _blake2 import blake2b
except ImportError:  # a Python built without it
    from hashlib import blake2b

FOLDER_NAME = ("nlos_cl", "programs-v1")
# PoCL's binaries carry every kernel's compiled code: 0.1-10 MB a program (the test suite builds
# ~100 programs, ~200 MB). Past this total, the least recently used are removed.
MAX_FOLDER_BYTES = 512 << 20
STALE_TMP_S = 3600.0  # a .tmp this old belongs to no living writer


def cache_folder() -> Path:
    """Under XDG_CACHE_HOME (devices.py has made sure it is writable), else ~/.cache."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base, *FOLDER_NAME)


def _key(device, text: str, options) -> str:
    platform = device.platform
    said = "\0".join([text, *options, platform.vendor, platform.name, platform.version,
                      device.vendor, device.name, device.version, device.driver_version])
    return blake2b(said.encode(), digest_size=32).hexdigest()


def load(context, device, text: str, options, folder: Path | None = None):
    """The program built from its stored binary, or None (none stored, or it was refused)."""
    path = (folder or cache_folder()) / f"{_key(device, text, options)}.bin"
    try:
        binary = path.read_bytes()
        os.utime(path)  # its time says when it was last used (evict())
    except OSError:
        return None
    try:
        program = cl.Program(context, [device], [binary])
        with warnings.catch_warnings():  # as runtime.build_program: the log is no user's news
            warnings.simplefilter("ignore", cl.CompilerWarning)
            program.build(options=list(options))
        return program
    except (cl.Error, ValueError):  # stale or damaged: build from source, store anew
        return None


def store(program, device, text: str, options, folder: Path | None = None) -> None:
    """Keep a program just built from source (written whole, then renamed into place, so a
    process that reads it meanwhile sees the old file or the new one, never a part)."""
    folder = folder or cache_folder()
    try:
        binaries = program.get_info(cl.program_info.BINARIES)
        devices = program.get_info(cl.program_info.DEVICES)
        binary = binaries[devices.index(device)]
        if not binary:
            return
        folder.mkdir(parents=True, exist_ok=True)
        handle, tmp = tempfile.mkstemp(dir=folder, suffix=".tmp")
        try:
            with os.fdopen(handle, "wb") as fh:
                fh.write(binary)
            os.replace(tmp, folder / f"{_key(device, text, options)}.bin")
        except BaseException:
            os.unlink(tmp)
            raise
        evict(folder)
    except (OSError, cl.Error, ValueError):
        pass  # not kept: the next process builds from source again


def evict(folder: Path, max_bytes: int = MAX_FOLDER_BYTES) -> None:
    """Remove the least recently used binaries until the folder holds at most max_bytes (run
    after each store, so only processes that built something pay for the listing)."""
    entries = []
    for path in folder.glob("*.tmp"):  # left by a writer that was killed mid-write
        try:
            if time.time() - path.stat().st_mtime > STALE_TMP_S:
                path.unlink()
        except OSError:
            pass
    for path in folder.glob("*.bin"):
        try:
            st = path.stat()
        except OSError:  # removed meanwhile by another process
            continue
        entries.append((st.st_mtime, st.st_size, path))
    total = sum(size for _, size, _ in entries)
    for _, size, path in sorted(entries):
        if total <= max_bytes:
            break
        try:
            path.unlink()
        except OSError:
            pass
        total -= size
