"""Issue 59 item 6 for y-tal captures and sequences (hypothesis): a valid file built, then a
field replaced by a lying or mistyped one (declared shapes up to 10^9 values never written,
wrong dtypes, empty or compound values, deflate chunks that inflate past their size, frame
counts and timestamps that disagree), or the file cut short. read_capture / read_sequence (every
frame) answer valid histograms or an InputError of one line naming the file and a fix, under a
64 MiB budget; byte flips are test_capture_safety's (HDF5 itself can crash on those)."""
import zlib

import h5py
import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import nlos_cl as nl
from nlos_cl.core.errors import InputError
from nlos_cl.tracking import read_sequence, write_sequence

FUZZ = settings(max_examples=40, deadline=5000, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])
C = nl.SPEED_OF_LIGHT
SPOTS = np.array([[-0.5, 0, 0], [-1.0, 0, 0], [-1.5, 0, 0]])
FIELDS = ["H", "H_format", "delta_t", "t_start", "sensor_grid_xyz", "laser_grid_xyz",
          "scene_info", "t_accounts_first_and_last_bounces", "sensor_xyz"]
SEQUENCE_FIELDS = FIELDS + ["frame_t_s", "frame_truths"]


def hist(k=0, n_bins=64):
    data = (k + 1.0) * (1.0 + np.arange(3 * n_bins).reshape(3, n_bins) % 7)
    return nl.HistogramSet(data, nl.TimeAxis(2 * 20 / C, 10e-12, n_bins), SPOTS, [0, 0, 0],
                           nl.PathCalibration(C, [-40.0]), truth=[0.1, 1.0, 0.0])


def values(kind: str, shape: tuple):
    """A value of `kind` (for create_dataset's data), or None where it is declared only."""
    if kind == "text":
        return np.array(b"1e-11 m")
    if kind == "bytes":
        return np.void(b"\x00" * 8)
    if kind == "empty":
        return h5py.Empty("f4")
    if kind == "compound":
        return np.zeros(shape, dtype=[("re", "f4"), ("im", "f4")])
    if kind == "strings":
        return np.array(["x" * 100] * max(int(np.prod(shape)), 1), dtype=object)
    dtype = {"int8": np.int8, "bool": np.bool_, "float16": np.float16, "float64": np.float64,
             "nan": np.float32, "huge": np.float64}[kind]
    fill = np.nan if kind == "nan" else 1e300 if kind == "huge" else 1
    return np.full(shape, fill).astype(dtype)


LIE = st.one_of(
    st.tuples(st.just("value"), st.sampled_from(["text", "bytes", "empty", "compound", "strings",
                                                 "int8", "bool", "float16", "float64", "nan",
                                                 "huge"]),
              st.lists(st.integers(0, 70), min_size=0, max_size=3).map(tuple)),
    st.tuples(st.just("declared"), st.sampled_from(["f4", "f8", "i2"]),
              st.lists(st.sampled_from([0, 1, 3, 64, 10 ** 4, 10 ** 9]), min_size=1,
                       max_size=4).map(tuple)),
    st.tuples(st.just("bomb"), st.sampled_from(["f4"]),
              st.sampled_from([(1 << 10,), (1 << 20,), (200 << 20,)])),
    st.tuples(st.just("cut"), st.just(""), st.integers(1, 99).map(lambda p: (p,))))


def lie(path, field: str, how):
    """`field` of the file at `path` replaced as `how` says (or the file cut short)."""
    kind, dtype, shape = how
    if kind == "cut":
        raw = path.read_bytes()
        path.write_bytes(raw[:len(raw) * shape[0] // 100])
        return
    with h5py.File(path, "a") as f:
        old = f[field].shape if field in f else (3,)
        if field in f:
            del f[field]
        if kind == "value":
            data = values(dtype, shape)
            f.create_dataset(field, data=data, **({"dtype": h5py.string_dtype()}
                                                  if dtype == "strings" else {}))
        elif kind == "declared":  # chunks never written: the file stays small
            chunks = tuple(max(1, min(s, 64)) for s in shape) if all(shape) else None
            f.create_dataset(field, shape=shape, dtype=dtype, chunks=chunks)
        else:  # one deflate chunk of the old shape's size, inflating to shape[0] bytes
            n = int(np.prod(old))
            d = f.create_dataset(field, (n,), dtype=dtype, chunks=(n,), compression="gzip")
            d.id.write_direct_chunk((0,), zlib.compress(bytes(shape[0]), 9), filter_mask=0)


def answered_well(read, path) -> None:
    try:
        sets = read()
    except InputError as exc:
        text = str(exc)
        assert "\n" not in text and path.name in text and "Fix:" in text, text
        assert len(text) < 600, text
        return
    for h in sets:  # valid histograms: HistogramSet checked them; finite, as read
        assert np.all(np.isfinite(h.data)) and h.data.shape[0] == h.n_detectors


@FUZZ
@given(field=st.sampled_from(FIELDS), how=LIE)
def test_capture_reader_under_lies(tmp_path_factory, field, how):
    folder = tmp_path_factory.mktemp("cap")
    path = nl.write_capture(folder / "c.h5", hist(), compression=0)
    lie(path, field, how)
    with _budget():
        answered_well(lambda: nl.read_capture(path), path)


@FUZZ
@given(field=st.sampled_from(SEQUENCE_FIELDS), how=LIE)
def test_sequence_reader_under_lies(tmp_path_factory, field, how):
    folder = tmp_path_factory.mktemp("seq")
    path = write_sequence(folder / "s.h5", [(0.1 * k, hist(k)) for k in range(3)])
    lie(path, field, how)
    with _budget():
        answered_well(lambda: [fr.histograms for fr in read_sequence(path)], path)


class _budget:
    def __enter__(self):
        import os
        self.old = os.environ.get("NLOS_CL_MEMORY_LIMIT")
        os.environ["NLOS_CL_MEMORY_LIMIT"] = "64M"

    def __exit__(self, *exc):
        import os
        if self.old is None:
            os.environ.pop("NLOS_CL_MEMORY_LIMIT", None)
        else:
            os.environ["NLOS_CL_MEMORY_LIMIT"] = self.old
