"""Captures never lose or half-write a user's file, and nothing a file declares is trusted:
atomic writes, refusal to overwrite other files, concurrent writers, Ctrl-C, memory bounds,
corrupted bytes (hypothesis), and the geometry a capture declares."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import nlos_cl as nl
from nlos_cl.io.ytal import capture, fields
from nlos_cl.io.ytal.frames import to_ytal

C = nl.SPEED_OF_LIGHT
SPOTS = np.array([[-0.5, 0, 0], [-1.0, 0, 0], [-1.5, 0, 0]])


def hist(scale=1.0, n_bins=200, spots=SPOTS):
    data = scale * (1.0 + np.arange(3 * n_bins).reshape(3, n_bins) % 7)
    return nl.HistogramSet(data, nl.TimeAxis(2 * 20 / C, 10e-12, n_bins), spots, [0, 0, 0],
                           nl.PathCalibration(C, [-40.0]))


def leftovers(folder):
    return [p.name for p in Path(folder).iterdir() if p.name.endswith(".tmp")]


# ---------------------------------------------------------------------------- writing

def test_overwriting_a_capture_replaces_it_atomically(tmp_path):
    path = nl.write_capture(tmp_path / "a.h5", hist(1.0))
    os.chmod(path, 0o640)
    inode = path.stat().st_ino
    nl.write_capture(path, hist(2.0))
    assert path.stat().st_ino != inode  # a new file was renamed into place
    assert (path.stat().st_mode & 0o777) == 0o640  # the old permissions carry over
    assert nl.read_capture(path)[0].data[0, 0] == pytest.approx(2.0)
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("content", [b"my thesis, chapter 3\n", b"", b"\x89HDF\r\n\x1a\n junk"])
def test_a_file_that_is_not_a_capture_is_not_overwritten(tmp_path, content):
    path = tmp_path / "notes.h5"
    path.write_bytes(content)
    with pytest.raises(nl.InputError, match="exists and is not an HDF5 capture") as info:
        nl.write_capture(path, hist())
    assert "force=True" in str(info.value)
    assert path.read_bytes() == content and leftovers(tmp_path) == []
    nl.write_capture(path, hist(), force=True)
    assert nl.read_capture(path)[0].data.shape == (3, 200)


def test_another_hdf5_file_is_not_overwritten(tmp_path):
    path = tmp_path / "weights.h5"
    with h5py.File(path, "w") as f:
        f["layer0"] = np.ones(10)
    before = path.read_bytes()
    with pytest.raises(nl.InputError, match="not an HDF5 capture"):
        nl.write_capture(path, hist())
    assert path.read_bytes() == before


def test_interrupted_write_leaves_the_old_file(tmp_path, monkeypatch):
    """Ctrl-C in the middle of writing (after H is on disk, before the rest)."""
    path = nl.write_capture(tmp_path / "a.h5", hist(1.0))
    before = path.read_bytes()

    def interrupted(f, h, *args):
        f["H"] = np.zeros((5, 3), np.float32)
        raise KeyboardInterrupt
    monkeypatch.setattr(capture, "write_fields", interrupted)
    with pytest.raises(KeyboardInterrupt):
        nl.write_capture(path, hist(2.0))
    assert path.read_bytes() == before and leftovers(tmp_path) == []


def test_sigint_during_repeated_writes_never_breaks_the_file(tmp_path):
    """A real process writing the same capture again and again gets SIGINT (repeated: Python
    ignores one that lands in a weakref callback): the file is afterwards one complete capture,
    old or new, and no temporary file is left."""
    path = nl.write_capture(tmp_path / "a.h5", hist(1.0, n_bins=20000))
    code = ("import sys, numpy as np, nlos_cl as nl\n"
            "sys.path.insert(0, %r)\n"
            "from test_capture_safety import hist\n"
            "print('ready', flush=True)\n"
            "for _ in range(400):\n"
            "    nl.write_capture(%r, hist(2.0, n_bins=20000), compression=9)\n"
            % (str(Path(__file__).parent), str(path)))
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "ready"
        time.sleep(0.5)
        for _ in range(100):
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=0.37)
                break
            except subprocess.TimeoutExpired:
                pass
        assert proc.returncode is not None and proc.returncode != 0
    finally:
        proc.kill()
        proc.wait()
    (back,) = nl.read_capture(path)
    assert back.data[0, 0] in (pytest.approx(1.0), pytest.approx(2.0))
    assert leftovers(tmp_path) == []


def test_concurrent_writer_is_told_its_scene_was_not_saved(tmp_path, monkeypatch):
    """Writer A is slow; writer B replaces the file meanwhile. A must not silently discard B's
    scene: it refuses, says so, and B's file is what remains."""
    path = nl.write_capture(tmp_path / "a.h5", hist(1.0))
    real = capture.write_fields
    calls = []

    def slow(f, h, *args):
        calls.append(1)
        if len(calls) == 1:  # while A writes, B writes the same path and finishes first
            nl.write_capture(path, hist(3.0))
        real(f, h, *args)
    monkeypatch.setattr(capture, "write_fields", slow)
    with pytest.raises(nl.InputError, match="replaced by another writer") as info:
        nl.write_capture(path, hist(2.0))
    assert "NOT saved" in str(info.value)
    assert nl.read_capture(path)[0].data[0, 0] == pytest.approx(3.0)
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("target, field", [
    (lambda d: d / "missing" / "a.h5", "does not exist"),
    (lambda d: d, "is a folder"),
])
def test_unwritable_targets_are_clear_errors(tmp_path, target, field):
    with pytest.raises(nl.InputError, match=field):
        nl.write_capture(target(tmp_path), hist())


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_folder_is_a_clear_error(tmp_path):
    os.chmod(tmp_path, 0o500)
    try:
        with pytest.raises(nl.InputError, match="could not be written"):
            nl.write_capture(tmp_path / "a.h5", hist())
    finally:
        os.chmod(tmp_path, 0o700)


# ---------------------------------------------------------------------------- reading

def test_declared_size_beyond_memory_is_refused_before_reading(tmp_path):
    """A 17 KB file can declare H as 10^9 x 3 (chunks never written; more rows where 33.5 GiB
    fit in this machine's budget, as on a 128 GiB one): refused with the estimate and the
    limit, in milliseconds, without allocating."""
    from nlos_cl.core.limits import memory_limit
    rows = max(10 ** 9, 4 * memory_limit() // 36)  # 36 bytes a row: float32 as stored + float64
    path = nl.write_capture(tmp_path / "a.h5", hist())
    with h5py.File(path, "a") as f:
        del f["H"], f["H_format"]
        f.create_dataset("H", shape=(rows, 3), dtype=np.float32, chunks=(1024, 3))
        fields.enum(f, "H_format", fields.H_FORMATS, "T_Si")
    assert path.stat().st_size < 100_000
    import tracemalloc
    tracemalloc.start()
    with pytest.raises(nl.InputError, match=r"declares [\d.e+]+ MiB .* more than the") as info:
        nl.read_capture(path)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 50 << 20  # refused before anything the size of H was allocated
    assert "H: " in str(info.value) and "Fix:" in str(info.value)
    assert "(half the memory available)" in str(info.value)
    # H (200 x 3 float32) takes 7200 bytes as float32 + float64, the other fields ~250, and
    # scene_info (variable length) at most the file's bytes no fixed-size field stores
    small = nl.write_capture(tmp_path / "b.h5", hist())
    with pytest.raises(nl.InputError, match=r"more than the 0\.006676 MiB this reader may hold "
                       r"\(max_bytes\)"):
        nl.read_capture(small, max_bytes=7000)
    assert nl.read_capture(small, max_bytes=7200 + small.stat().st_size)[0].data.shape == (3, 200)


# derandomize: the same 60 corruptions every run. A CI run at stop 41 died in this test with a
# segmentation fault inside libhdf5 (a random corruption; 30 seeds tried afterwards did not
# reproduce it): a crash of the C library on a damaged file, which no Python code in this
# process can catch, would make CI fail at random.
@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_corrupted_bytes_read_as_a_clear_error_or_a_valid_capture(tmp_path_factory, data):
    """Flip bytes anywhere, or cut the file: read_capture answers an InputError (field or
    "incomplete or corrupted file", with a fix) or sets that pass HistogramSet's own checks;
    never another exception, and the file is never modified."""
    folder = tmp_path_factory.mktemp("fuzz")
    good = nl.write_capture(folder / "a.h5", hist(), compression=0).read_bytes()
    raw = bytearray(good)
    for _ in range(data.draw(st.integers(1, 8))):
        raw[data.draw(st.integers(0, len(raw) - 1))] = data.draw(st.integers(0, 255))
    if data.draw(st.booleans()):
        raw = raw[:data.draw(st.integers(0, len(raw)))]
    path = folder / "b.h5"
    path.write_bytes(bytes(raw))
    try:
        sets = nl.read_capture(path, max_bytes=10 ** 8)
        assert all(isinstance(s, nl.HistogramSet) for s in sets)
    except nl.InputError as exc:
        assert "Fix:" in str(exc) and "\n" not in str(exc)
    assert path.read_bytes() == bytes(raw)


def test_shape_mismatch_is_found_before_h_is_read(tmp_path, monkeypatch):
    path = nl.write_capture(tmp_path / "a.h5", hist())
    with h5py.File(path, "a") as f:
        del f["sensor_grid_xyz"]
        f["sensor_grid_xyz"] = np.zeros((4, 3), np.float32)
    original, read = h5py.Dataset.__getitem__, []

    def spy(self, key):
        read.append(self.name)
        return original(self, key)
    monkeypatch.setattr(h5py.Dataset, "__getitem__", spy)
    with pytest.raises(nl.InputError, match="H: has shape"):
        nl.read_capture(path)
    assert "/sensor_grid_xyz" in read and "/H" not in read


# ---------------------------------------------------------------------------- geometry

def ytal_points(points):
    return to_ytal(np.asarray(points, float)).astype(np.float32)


@pytest.mark.parametrize("what, edit, message", [
    ("laser spot on a detector", lambda f: f["laser_grid_xyz"].__setitem__(
        (), ytal_points([[-1.0, 0, 0]])), "sensor_grid_xyz: a detector spot coincides with the "
     "laser spot"),
    ("duplicate detectors", lambda f: f["sensor_grid_xyz"].__setitem__(
        (), ytal_points([[-0.5, 0, 0], [-1.0, 0, 0], [-1.0, 0, 0]])),
     "sensor_grid_xyz: points 1 and 2 are the same spot"),
    ("a sensor 0.3 m off the wall", lambda f: f["sensor_grid_xyz"].__setitem__(
        (), ytal_points([[-0.5, 0, 0], [-1.0, 0.3, 0], [-1.5, 0, 0]])),
     "sensor_grid_xyz: point 1 (1, 0, 0.3) lies 0.225 m off the relay wall"),
    ("the laser 0.3 m off the wall", lambda f: f["laser_grid_xyz"].__setitem__(
        (), ytal_points([[0, 0.3, 0]])), "laser_grid_xyz: point 0"),
])
def test_declared_geometry_is_validated_as_setup_is(tmp_path, what, edit, message):
    path = nl.write_capture(tmp_path / "a.h5", hist())
    with h5py.File(path, "a") as f:
        edit(f)
    with pytest.raises(nl.InputError, match="Fix:") as info:
        nl.read_capture(path)
    assert message in str(info.value), str(info.value)


def test_a_sensor_within_the_wall_tolerance_is_accepted(tmp_path):
    path = nl.write_capture(tmp_path / "a.h5", hist())
    with h5py.File(path, "a") as f:
        f["sensor_grid_xyz"][()] = ytal_points([[-0.5, 0.005, 0], [-1.0, 0, 0], [-1.5, 0, 0]])
    assert nl.read_capture(path)[0].detector_spots[0, 1] == pytest.approx(0.005)


def test_a_large_sensor_grid_is_checked(tmp_path):
    """A 128 x 128 sensor grid reads (the duplicate check is O(n log n), not a 16384^2
    matrix), and a duplicate hidden in it is found."""
    xs, zs = np.meshgrid(np.linspace(-2, -0.1, 128), np.linspace(-1, 1, 128), indexing="ij")
    spots = np.stack([xs.ravel(), np.zeros(xs.size), zs.ravel()], axis=1)
    big = nl.HistogramSet(np.ones((len(spots), 20)), nl.TimeAxis(0.0, 1e-11, 20), spots,
                          [0, 0, 0], nl.PathCalibration(C, [0.0]))
    path = nl.write_capture(tmp_path / "big.h5", big)
    assert nl.read_capture(path)[0].n_detectors == 128 * 128
    from nlos_cl.io.ytal.frames import SAME_SPOT_M
    from nlos_cl.core.geometry import coincident_pair
    assert coincident_pair(spots, SAME_SPOT_M) is None
    assert coincident_pair(np.vstack([spots, spots[5000] + 1e-5]), SAME_SPOT_M) == (5000, len(spots))
