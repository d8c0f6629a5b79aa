"""Finding an OpenCL device: an explicit choice, else PYOPENCL_CTX, else the best one found.

Copes with platforms that fail to list devices, with two platforms of the same name (PyPI's
PoCL beside Debian's), and with none at all (an error that says how to install one).
"""
from __future__ import annotations

import os
import re
import stat
import tempfile
from dataclasses import dataclass


def _writable(folder: str) -> bool:
    """Whether files can be created in `folder` (made if missing). Tried, not os.access: a
    read-only mount or a HOME that is a file answer only to a real attempt."""
    try:
        os.makedirs(folder, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            return True
    except OSError:
        return False


def _private_temp_cache() -> str:
    """A cache folder under the temporary directory that only this user can write: the same one
    run after run (kernels stay cached), unless someone else made that name first."""
    folder = os.path.join(tempfile.gettempdir(), f"nlos_cl-cache-{os.getuid()}")
    try:
        os.makedirs(folder, mode=0o700, exist_ok=True)
        st = os.lstat(folder)
        if stat.S_ISDIR(st.st_mode) and st.st_uid == os.getuid() and not st.st_mode & 0o077:
            return folder
    except OSError:
        pass
    return tempfile.mkdtemp(prefix="nlos_cl-cache-")


def _ensure_writable_cache() -> None:
    """PoCL (kernel binaries), pyopencl and pytools (its program cache) keep caches under
    XDG_CACHE_HOME, by default ~/.cache. If that folder cannot be written (HOME on a read-only
    mount, or no HOME), PoCL silently lists zero devices and pytools fails with an
    AttributeError; point XDG_CACHE_HOME at a private temporary folder instead and say so
    once. Must run before pyopencl loads the ICDs."""
    cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    if _writable(cache):
        return
    fallback = _private_temp_cache()
    os.environ["XDG_CACHE_HOME"] = fallback
    from ..core.errors import warn  # (core holds no device code: safe before pyopencl)
    warn(f"cache folder {cache} is not writable: OpenCL kernels are cached in {fallback} "
         "instead. Fix: set XDG_CACHE_HOME to a writable folder", RuntimeWarning)


_ensure_writable_cache()

import pyopencl as cl  # noqa: E402  (after the cache folder is known to be writable)

from ..core.errors import DeviceError, shown  # noqa: E402

INSTALL_HELP = (
    "No OpenCL device found. Install an OpenCL runtime: on Debian/Ubuntu "
    "`sudo apt-get install pocl-opencl-icd` (PoCL, CPU; the fastest choice here), elsewhere "
    "`pip install pocl-binary-distribution`; for GPUs, the vendor's driver (NVIDIA, AMD, Intel). "
    "If PoCL is installed but lists no device, its cache folder may not be writable: set "
    "POCL_CACHE_DIR or XDG_CACHE_HOME to a writable folder. `nlos-cl info` lists what is found."
)

_TYPE_RANK = {cl.device_type.GPU: 3, cl.device_type.ACCELERATOR: 2, cl.device_type.CPU: 1}


@dataclass(frozen=True)
class DeviceEntry:
    platform_index: int
    device_index: int
    platform: "cl.Platform"
    device: "cl.Device"

    @property
    def label(self) -> str:
        return (f"[{self.platform_index}:{self.device_index}] {self.device.name.strip()} "
                f"({self.platform.name.strip()}, {self.platform.version.strip()})")


# Address space an OpenCL runtime and its first kernel builds take beyond what the process has
# already mapped. Measured with a cold kernel cache (PoCL 3.1, LLVM 15, 2 cores) by the highest
# `ulimit -v` that fails and the lowest that works: `nlos-cl locate` needs 498-537 MiB more,
# `nlos-cl simulate` 472-521 MiB; 600 MiB leaves ~10 % margin (PoCL's worker threads, hence
# this number, grow with the core count). Below it PoCL aborts inside LLVM (an assertion),
# raises std::bad_alloc mid-build or deadlocks: none of them catchable, so refuse up front.
RUNTIME_ADDRESS_SPACE_MIB = 600


def check_address_space(need_mib: int = RUNTIME_ADDRESS_SPACE_MIB) -> None:
    """Refuse, in one line, to start an OpenCL runtime under an address-space limit (ulimit -v,
    RLIMIT_AS) too small for it; no limit, or no way to read one (not Linux), passes."""
    try:
        import resource
        limit = resource.getrlimit(resource.RLIMIT_AS)[0]
        if limit == resource.RLIM_INFINITY:
            return
        with open("/proc/self/status") as status:
            mapped_kib = next(int(ln.split()[1]) for ln in status if ln.startswith("VmSize:"))
    except (ImportError, OSError, StopIteration, ValueError):
        return
    mib = 1 << 20
    if limit - mapped_kib * 1024 < need_mib * mib:
        want = mapped_kib // 1024 + need_mib
        raise DeviceError(f"ulimit -v: the address-space limit is {limit // mib} MiB, of which "
                          f"{mapped_kib // 1024} MiB are already mapped; an OpenCL runtime and "
                          f"its kernel builds need ~{need_mib} MiB more (PoCL would abort or "
                          f"hang). Fix: raise the limit to at least {want} MiB "
                          f"(ulimit -v {want * 1024}) or lift it (ulimit -v unlimited)")


def list_devices() -> list[DeviceEntry]:
    """Every (platform, device) pair that answers; platforms that fail to list are skipped."""
    check_address_space()  # before PoCL loads LLVM: under a tight ulimit -v it aborts inside
    try:
        platforms = cl.get_platforms()
    except cl.Error:  # no ICD at all, or the loader found no platform
        return []
    found = []
    for p_index, platform in enumerate(platforms):
        try:
            devices = platform.get_devices()
        except cl.Error:  # e.g. PoCL with no usable device
            continue
        found.extend(DeviceEntry(p_index, d_index, platform, dev)
                     for d_index, dev in enumerate(devices))
    return found


def _runtime_version(entry: DeviceEntry) -> tuple:
    """(major, minor, not-a-release-candidate) of the implementation, e.g. PoCL 3.1 > 3.0-rc2."""
    match = re.search(r"(\d+)\.(\d+)(\S*)", entry.platform.version.split("OpenCL", 1)[-1]
                      .split(" ", 2)[-1])
    if not match:
        return (0, 0, 0)
    return (int(match.group(1)), int(match.group(2)), 0 if "rc" in match.group(3) else 1)


def _rank(entry: DeviceEntry) -> tuple:
    dev = entry.device
    return (_TYPE_RANK.get(dev.type, 0), _runtime_version(entry),
            dev.max_compute_units * max(dev.max_clock_frequency, 1), -entry.platform_index)


def choose_device(spec=None) -> "cl.Device":
    """spec: a pyopencl Device, 'P:D' or 'P' indices, or a substring of the device or platform
    name. None: PYOPENCL_CTX if set, else the best device (GPU before CPU; of two same-named
    platforms the newer implementation)."""
    if isinstance(spec, cl.Device):
        return spec
    entries = list_devices()
    if not entries:
        raise DeviceError(INSTALL_HELP)
    if spec is None:
        spec = os.environ.get("PYOPENCL_CTX") or None
    if spec is None:
        return max(entries, key=_rank).device
    text = str(spec).strip()
    if re.fullmatch(r"\d+(:\d+)?", text):
        p, _, d = text.partition(":")
        picked = [e for e in entries
                  if e.platform_index == int(p) and e.device_index == int(d or 0)]
    else:
        low = text.lower()
        picked = [e for e in entries
                  if low in e.device.name.lower() or low in e.platform.name.lower()]
    if not picked:
        listing = "; ".join(e.label for e in entries)
        raise DeviceError(f"device: {shown(text)} (from the device argument or PYOPENCL_CTX) "
                          f"matches no OpenCL device. Available: {listing}. Fix: pass 'P:D' indices "
                          f"or part of a name from that list")
    return max(picked, key=_rank).device


def describe(device: "cl.Device") -> str:
    return (f"{device.name.strip()} on {device.platform.name.strip()} "
            f"({device.platform.version.strip()})")
