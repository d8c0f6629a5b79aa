"""Issue 59, the gate by other routes (hypothesis): HDF5 attributes (how many, how large, what
type, on which object) and compression filters the gate cannot bound, in captures and MATLAB
v7.3 files; the units of a dataset reader's lengths and bin widths. Each reader answers
correctly or with one line naming the file and a fix, within a small memory budget."""
import zlib

import h5py
import numpy as np
import pytest
import scipy.io
from hypothesis import HealthCheck, given, reject, settings
from hypothesis import strategies as st

import nlos_cl as nl
from nlos_cl.core.errors import InputError
from nlos_cl.io.datasets import read_dataset
from nlos_cl.io.datasets.matfile import load

FUZZ = settings(max_examples=25, deadline=10000, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])
C = nl.SPEED_OF_LIGHT
SPOTS = np.array([[-0.5, 0, 0], [-1.0, 0, 0], [-1.5, 0, 0]])
PLUGINS = [32001, 32004, 32008, 32013, 32015, 307, 4000]  # blosc, lz4, bitshuffle, zfp, zstd...


def one_line(exc: InputError, path) -> None:
    text = str(exc)
    assert "\n" not in text and path.name in text and "Fix:" in text, text
    assert len(text) < 600, text


class budget:
    def __init__(self, value="4M"):
        self.value = value

    def __enter__(self):
        self.mp = pytest.MonkeyPatch()
        self.mp.setenv("NLOS_CL_MEMORY_LIMIT", self.value)

    def __exit__(self, *exc):
        self.mp.undo()


def capture(folder):
    data = 1.0 + np.arange(3 * 64).reshape(3, 64) % 7
    h = nl.HistogramSet(data, nl.TimeAxis(2 * 20 / C, 10e-12, 64), SPOTS, [0, 0, 0],
                        nl.PathCalibration(C, [-40.0]))
    src = nl.write_capture(folder / "src.h5", h, compression=0)
    path = folder / "c.h5"
    # copied into a file of the latest format, whose objects hold attributes of any size
    with h5py.File(src, "r") as a, h5py.File(path, "w", libver="latest") as b:
        for key in a:
            a.copy(a[key], b, name=key)
        b.attrs.update(a.attrs)
    return path


def mat73(path, cube):
    with h5py.File(path, "w", userblock_size=512, libver="latest") as f:
        f["rect_data"] = cube.T
        f["width"] = np.array([[0.3]])
        for name in ("rect_data", "width"):
            f[name].attrs["MATLAB_class"] = np.bytes_(b"double")
    with open(path, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, HDF5 schema 1.00 .".ljust(116) + bytes(8) + b"\x00\x02IM")
    return path


ATTRIBUTE = st.tuples(
    st.sampled_from(["/", "H", "rect_data", "width"]),           # on which object
    st.sampled_from(["notes", "MATLAB_class", "MATLAB_empty"]),  # under which name
    st.sampled_from(["f8", "u1", "S8", "vlen", "i4"]),           # of which type
    st.sampled_from([(), (1,), (2,), (1000,), (1 << 20,)]),      # of which shape
    st.integers(1, 3))                                           # how many copies


def add_attribute(path, how) -> None:
    where, name, kind, shape, copies = how
    with h5py.File(path, "r+", libver="latest") as f:
        obj = f.get(where, f)
        for i in range(copies):
            key = name if i == 0 else f"{name}{i}"
            try:
                _create(obj, key, kind, shape)
            except OSError:  # an old-format object header holds no large attribute
                reject()


def _create(obj, key, kind, shape) -> None:
    if kind == "vlen":
        obj.attrs.create(key, np.full(shape, "x" * 40, dtype=object), dtype=h5py.string_dtype())
    elif kind == "S8":
        obj.attrs.create(key, np.full(shape, b"double", dtype="S8"))
    else:
        obj.attrs.create(key, np.ones(shape, dtype=kind))


@FUZZ
@given(how=ATTRIBUTE)
def test_capture_attributes_answered_within_budget(tmp_path_factory, how):
    path = capture(tmp_path_factory.mktemp("cap"))
    add_attribute(path, how)
    with budget():
        try:
            (h,) = nl.read_capture(path)
        except InputError as exc:
            one_line(exc, path)
            return
    assert np.all(np.isfinite(h.data)) and h.data.shape == (3, 64)


@FUZZ
@given(how=ATTRIBUTE)
def test_matlab_attributes_answered_within_budget(tmp_path_factory, how):
    path = mat73(tmp_path_factory.mktemp("mat") / "r.mat", np.ones((4, 4, 32)))
    add_attribute(path, how)
    with budget():
        try:
            cube = load(path, "rect_data", 3)
        except InputError as exc:
            one_line(exc, path)
            return
    assert cube.shape == (4, 4, 32)


def test_attributes_past_the_budget_are_refused_unread(tmp_path):
    """A 12 MB attribute under a 4 MiB budget: refused by its declared size."""
    path = capture(tmp_path)
    with h5py.File(path, "r+", libver="latest") as f:
        f.attrs.create("notes", np.zeros(3 << 20, np.float32))
    with budget(), pytest.raises(InputError, match="MiB of HDF5 attributes") as exc:
        nl.read_capture(path)
    one_line(exc.value, path)


def test_matlab_class_of_many_values_is_refused(tmp_path):
    """MATLAB_class as an array: one line (it was a ValueError from .item())."""
    path = mat73(tmp_path / "r.mat", np.ones((4, 4, 32)))
    with h5py.File(path, "r+", libver="latest") as f:
        del f["rect_data"].attrs["MATLAB_class"]
        f["rect_data"].attrs["MATLAB_class"] = np.zeros(1000)
    with pytest.raises(InputError, match="attribute MATLAB_class: holds") as exc:
        load(path, "rect_data", 3)
    one_line(exc.value, path)


def plugin_chunked(f, name, data, filter_id):
    """`name` in f stored as one chunk marked compressed by `filter_id` (no such plugin here:
    HDF5 cannot decode it; where one is installed it decodes with no bound)."""
    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_chunk(data.shape)
    dcpl.set_filter(filter_id, h5py.h5z.FLAG_OPTIONAL, (1, 2))
    space = h5py.h5s.create_simple(data.shape)
    tid = h5py.h5t.py_create(data.dtype)
    dsid = h5py.h5d.create(f.id, name.encode(), tid, space, dcpl=dcpl)
    dsid.write_direct_chunk((0,) * data.ndim, zlib.compress(data.tobytes()), filter_mask=0)
    return f[name]


@FUZZ
@given(filter_id=st.sampled_from(PLUGINS), shuffle=st.booleans(), field=st.sampled_from(
    ["H", "sensor_grid_xyz"]))
def test_capture_filters_the_gate_cannot_bound_are_refused(tmp_path_factory, filter_id,
                                                           shuffle, field):
    path = capture(tmp_path_factory.mktemp("cap"))
    with h5py.File(path, "r+") as f:
        data = f[field][()]
        del f[field]
        plugin_chunked(f, field, data, filter_id)
    with pytest.raises(InputError) as exc:
        nl.read_capture(path)
    one_line(exc.value, path)
    assert f"filter {filter_id}" in str(exc.value) and field in str(exc.value)


def test_matlab_filters_the_gate_cannot_bound_are_refused(tmp_path):
    path = mat73(tmp_path / "r.mat", np.ones((4, 4, 32)))
    with h5py.File(path, "r+") as f:
        data = f["rect_data"][()]
        del f["rect_data"]
        plugin_chunked(f, "rect_data", data, 32001).attrs["MATLAB_class"] = np.bytes_(b"double")
    with pytest.raises(InputError, match="filter 32001") as exc:
        load(path, "rect_data", 3)
    one_line(exc.value, path)


SCALE = st.sampled_from([1e-3, 1e-2, 1.0, 10.0, 100.0, 1000.0])


@FUZZ
@given(width=st.floats(0.05, 1.0), width_scale=SCALE, dt_ps=st.floats(1.0, 100.0),
       dt_scale=st.sampled_from([1e-12, 1e-3, 1.0, 1e3]), in_file=st.booleans())
def test_lct_units_answered_or_refused_at_the_reader(tmp_path_factory, width, width_scale,
                                                     dt_ps, dt_scale, in_file):
    """A width in mm or cm (in the file or --width) and a bin width in s or ns (--dt-ps): the
    reader's answer spans a wall with camera bins, or one line names the dataset and how the
    value was given."""
    path = tmp_path_factory.mktemp("lct") / "r.mat"
    cube = np.zeros((4, 4, 64))
    cube[..., 30] = 5.0
    given_width = width * width_scale
    scipy.io.savemat(path, {"rect_data": cube, "width": [[given_width if in_file else width]]})
    options = {"dt_ps": dt_ps * dt_scale} | ({} if in_file else {"width_m": given_width})
    try:
        h = read_dataset(path, "lct", **options)
    except InputError as exc:
        one_line(exc, path)
        assert given_width > 50 / 2 or dt_ps * dt_scale * 1e-12 < 1e-14 \
            or dt_ps * dt_scale * 1e-12 > 5e-9, str(exc)
        return
    assert np.ptp(h.detector_spots, axis=0).max() <= 50.0
    assert 1e-14 <= h.time_axis.dt_s <= 5.1e-9


def test_ccsocr_grid_in_centimetres_names_the_option(tmp_path):
    folder = tmp_path / "cc"
    folder.mkdir()
    scipy.io.savemat(folder / "sub_Sig.mat", {"sub_Sig": np.ones((4, 64))})
    pts = np.array([[0, 10, 0], [0, 20, 0], [0, 30, 0], [0, 40, 0]], float)
    scipy.io.savemat(folder / "C_i.mat", {"C_i": pts})
    scipy.io.savemat(folder / "C_d.mat", {"C_d": pts})
    with pytest.raises(InputError, match="grid-m") as exc:
        read_dataset(folder, "ccsocr", grid_m=10.0)
    one_line(exc.value, folder)
    assert read_dataset(folder, "ccsocr").n_detectors == 4  # 1 cm a wall index: right


def test_v5_file_of_many_variables_is_refused_quickly(tmp_path):
    """10^5 one-value variables before rect_data: refused after MAX_ELEMENTS tags (scipy
    walked every one, minutes for 10^6)."""
    import io
    import time
    one = io.BytesIO()
    scipy.io.savemat(one, {"x": [[1.0]]})
    body = io.BytesIO()
    scipy.io.savemat(body, {"rect_data": np.ones((2, 2, 3)), "width": [[0.3]]})
    raw = body.getvalue()
    path = tmp_path / "many.mat"
    path.write_bytes(raw[:128] + one.getvalue()[128:] * 100_000 + raw[128:])
    start = time.perf_counter()
    with pytest.raises(InputError, match="MATLAB variables") as exc:
        load(path, "rect_data", 3)
    assert time.perf_counter() - start < 5
    one_line(exc.value, path)


def keyhole(folder, position_m):
    """A Keyhole folder (v7.3 files) whose stage positions are `position_m`."""
    folder.mkdir()
    direct = np.zeros(2000)
    direct[600:620] = np.linspace(10, 1000, 20)
    files = {"direct_after": {"direct_after": direct[None, :]},
             "LongExpNoObject_after": {"LongExpNoObject_after": np.ones((1, 2000))},
             "scan_0": {"data": np.ones((3, 2000)), "xpos": np.full((1, 3), position_m),
                        "zpos": np.full((1, 3), position_m)}}
    for name, variables in files.items():
        with h5py.File(folder / f"{name}.mat", "w", userblock_size=512) as f:
            for key, value in variables.items():
                f[key] = value
                f[key].attrs["MATLAB_class"] = np.bytes_(b"double")
        with open(folder / f"{name}.mat", "r+b") as fh:
            fh.write(b"MATLAB 7.3 MAT-file, HDF5 schema 1.00 .".ljust(116) + bytes(8)
                     + b"\x00\x02IM")
    return folder


def test_keyhole_stage_in_millimetres_is_refused(tmp_path):
    frames, meta = read_dataset(keyhole(tmp_path / "m", 0.5), "keyhole")
    assert len(frames) == 3 and meta["xpos_m"] == [0.5] * 3  # metres: read as before
    with pytest.raises(InputError, match=r"_m: reaches \d+(\.\d+)? m, beyond") as exc:
        read_dataset(keyhole(tmp_path / "mm", 500.0), "keyhole")
    one_line(exc.value, tmp_path / "mm")
