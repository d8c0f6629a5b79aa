"""Finding an OpenCL device: an explicit choice, else PYOPENCL_CTX, else the best one found.

Copes with platforms that fail to list devices, with two platforms of the same name (PyPI's
PoCL beside Debian's), and with none at all (an error that says how to install one).
"""
from __future__ import annotations

import os
import re
import tempfile
from dataclasses import dataclass


def _ensure_pocl_cache() -> None:
    """PoCL silently lists zero devices when it cannot create its cache folder (by default
    under ~/.cache). If neither POCL_CACHE_DIR nor XDG_CACHE_HOME is set and ~/.cache is not
    writable, point PoCL at a temporary folder. Must run before pyopencl loads the ICDs."""
    if os.environ.get("POCL_CACHE_DIR") or os.environ.get("XDG_CACHE_HOME"):
        return
    cache = os.path.join(os.path.expanduser("~"), ".cache")
    try:
        os.makedirs(cache, exist_ok=True)
        if os.access(cache, os.W_OK):
            return
    except OSError:
        pass
    os.environ["POCL_CACHE_DIR"] = os.path.join(tempfile.gettempdir(), "nlos_cl-pocl-cache")


_ensure_pocl_cache()

import pyopencl as cl  # noqa: E402  (after the cache fix above)

from ..core.errors import DeviceError  # noqa: E402

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


def list_devices() -> list[DeviceEntry]:
    """Every (platform, device) pair that answers; platforms that fail to list are skipped."""
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
        raise DeviceError(f"device {text!r} (from the device argument or PYOPENCL_CTX) matches "
                          f"no OpenCL device. Available: {listing}. Fix: pass 'P:D' indices "
                          f"or part of a name from that list")
    return max(picked, key=_rank).device


def describe(device: "cl.Device") -> str:
    return (f"{device.name.strip()} on {device.platform.name.strip()} "
            f"({device.platform.version.strip()})")
