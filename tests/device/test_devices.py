"""Device choice: an argument, PYOPENCL_CTX, else the best; duplicates and none handled."""
from types import SimpleNamespace

import pytest

from nlos_cl.device import devices
from nlos_cl.core.errors import DeviceError

cl = devices.cl


def fake(p_index, platform_version, device_type=cl.device_type.CPU, name="cpu", units=2):
    platform = SimpleNamespace(name="Portable Computing Language", version=platform_version)
    device = SimpleNamespace(name=name, type=device_type, max_compute_units=units,
                             max_clock_frequency=3000, platform=platform)
    return devices.DeviceEntry(p_index, 0, platform, device)


def test_no_device_says_how_to_install(monkeypatch):
    monkeypatch.setattr(devices, "list_devices", lambda: [])
    with pytest.raises(DeviceError, match="apt-get install pocl-opencl-icd"):
        devices.choose_device()


def test_duplicate_pocl_platforms_prefer_the_newer_release(monkeypatch):
    pip_pocl = fake(0, "OpenCL 3.0 PoCL 3.0-rc2  Linux, Release, RELOC")
    debian_pocl = fake(1, "OpenCL 3.0 PoCL 3.1+debian  Linux, None+Asserts, RELOC")
    monkeypatch.setattr(devices, "list_devices", lambda: [pip_pocl, debian_pocl])
    monkeypatch.delenv("PYOPENCL_CTX", raising=False)
    assert devices.choose_device() is debian_pocl.device
    monkeypatch.setattr(devices, "list_devices", lambda: [debian_pocl, pip_pocl])
    assert devices.choose_device() is debian_pocl.device


def test_gpu_preferred_and_explicit_choice_wins(monkeypatch):
    cpu = fake(0, "OpenCL 3.0 PoCL 3.1")
    gpu = fake(1, "OpenCL 3.0 CUDA 12.4", cl.device_type.GPU, name="NVIDIA H100")
    monkeypatch.setattr(devices, "list_devices", lambda: [cpu, gpu])
    monkeypatch.delenv("PYOPENCL_CTX", raising=False)
    assert devices.choose_device() is gpu.device
    assert devices.choose_device("0:0") is cpu.device
    assert devices.choose_device("h100") is gpu.device
    monkeypatch.setenv("PYOPENCL_CTX", "0")
    assert devices.choose_device() is cpu.device
    with pytest.raises(DeviceError, match="matches no OpenCL device"):
        devices.choose_device("7:3")


def test_the_real_machine_has_a_device():
    assert devices.list_devices(), devices.INSTALL_HELP
