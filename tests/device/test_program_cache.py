"""Programs kept as the device's binaries (nlos_cl/device/programs.py): a second process loads
what the first built instead of asking the compiler again; a binary the implementation refuses
is rebuilt from source; a folder that cannot be written only costs the cache."""
import secrets

import numpy as np
import pyopencl as cl
import pytest

from nlos_cl.device import programs
from nlos_cl.device.runtime import Runtime

SOURCE = "__kernel void twice(__global float *a) { a[get_global_id(0)] *= SCALE; }\n"


@pytest.fixture
def folder(tmp_path, monkeypatch):
    where = tmp_path / "programs"
    monkeypatch.setattr(programs, "cache_folder", lambda: where)
    return where


def _unique_source(monkeypatch):
    """kernels/twice.cl as a source of its own, new to every cache (a fresh token)."""
    text = f"// {secrets.token_hex(8)}\n{SOURCE}"
    monkeypatch.setattr("nlos_cl.device.runtime.kernel_source", lambda name: text)
    return text


def _twice(rt: Runtime) -> np.ndarray:
    values = rt.from_numpy(np.arange(8, dtype=np.float32))
    rt.run(rt.kernel("twice", "twice", SCALE="2.0f"), (8,), values)
    return values.get(rt.queue)


def test_a_built_program_is_loaded_by_the_next_runtime(runtime, folder, monkeypatch):
    text = _unique_source(monkeypatch)
    first = Runtime(runtime.device)
    assert np.array_equal(_twice(first), 2 * np.arange(8))
    assert len(list(folder.glob("*.bin"))) == 1  # kept, whole (no temporary file left)
    second = Runtime(runtime.device)  # another context, as a new process would have
    assert programs.load(second.context, second.device, text, ("-DSCALE=2.0f",)) is not None
    assert np.array_equal(_twice(second), 2 * np.arange(8))
    # other options, another binary: a define never reads a program built without it
    assert programs.load(second.context, second.device, text, ("-DSCALE=3.0f",)) is None


def test_a_refused_binary_is_rebuilt_from_source(runtime, folder, monkeypatch):
    _unique_source(monkeypatch)
    _twice(Runtime(runtime.device))
    (stored,) = folder.glob("*.bin")
    stored.write_bytes(b"not a binary")
    assert np.array_equal(_twice(Runtime(runtime.device)), 2 * np.arange(8))
    assert stored.read_bytes() != b"not a binary"  # replaced by the rebuilt program's


def test_a_folder_that_cannot_be_written_only_costs_the_cache(runtime, tmp_path, monkeypatch):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    monkeypatch.setattr(programs, "cache_folder", lambda: blocker / "programs")
    _unique_source(monkeypatch)
    assert np.array_equal(_twice(Runtime(runtime.device)), 2 * np.arange(8))


def test_the_key_holds_source_options_and_device(runtime):
    key = programs._key(runtime.device, SOURCE, ("-DSCALE=2.0f",))
    assert key == programs._key(runtime.device, SOURCE, ("-DSCALE=2.0f",))
    assert key != programs._key(runtime.device, SOURCE + " ", ("-DSCALE=2.0f",))
    assert key != programs._key(runtime.device, SOURCE, ("-DSCALE=3.0f",))
    assert isinstance(runtime.device, cl.Device) and len(key) == 64


def test_the_least_recently_used_binaries_go_first(tmp_path):
    import os
    for name in ("new", "old", "middle"):
        (tmp_path / f"{name}.bin").write_bytes(b"x" * 100)
    for name, when in (("old", 1000), ("middle", 2000), ("new", 3000)):
        os.utime(tmp_path / f"{name}.bin", (when, when))
    programs.evict(tmp_path, max_bytes=150)
    assert sorted(p.stem for p in tmp_path.glob("*.bin")) == ["new"]


def test_a_loaded_binary_keeps_the_compiler_log_out_of_the_callers_warnings(runtime, folder,
                                                                           monkeypatch):
    """PoCL hands a loaded binary's build log back; pyopencl turned it into a CompilerWarning
    that locate_capture then reported as a warning about the answer ('Non-empty compiler
    output' in the draws' rows, on a warm cache only)."""
    import warnings
    text = f"// {secrets.token_hex(8)}\n#warning \"a note from the compiler\"\n{SOURCE}"
    monkeypatch.setattr("nlos_cl.device.runtime.kernel_source", lambda name: text)
    _twice(Runtime(runtime.device))  # built from source, stored
    second = Runtime(runtime.device)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert programs.load(second.context, second.device, text, ("-DSCALE=2.0f",))
    assert [str(w.message) for w in caught] == []
