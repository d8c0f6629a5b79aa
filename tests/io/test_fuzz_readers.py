"""Issue 59 item 6: property-based tests (hypothesis) of the readers the gate guards: mesh files,
MATLAB v5 files, consumer-nlos .npz frames, calibration CSVs, each built valid and then given
lying headers and counts, wrong dtypes and units, truncation, flipped bytes and hostile
containers. Every outcome is either a correct result or an InputError of one line naming the
file, under a 64 MiB budget (NLOS_CL_MEMORY_LIMIT) and a per-example deadline; small inputs and
few examples keep the whole file near 30 s on 2 cores."""
import bz2
import gzip
import io
import os
import struct
import zipfile
from contextlib import contextmanager

import numpy as np
import scipy.io
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import nlos_cl as nl
from nlos_cl.core.errors import InputError
from nlos_cl.io.calibration import read_calibration_pairs
from nlos_cl.io.datasets.matfile import load

FUZZ = settings(max_examples=60, deadline=5000, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])
BOX = trimesh.creation.box((0.3, 0.3, 1.6))


@contextmanager
def budget(text="64M"):
    old = os.environ.get("NLOS_CL_MEMORY_LIMIT")
    os.environ["NLOS_CL_MEMORY_LIMIT"] = text
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("NLOS_CL_MEMORY_LIMIT")
        else:
            os.environ["NLOS_CL_MEMORY_LIMIT"] = old


def refused_well(exc: InputError, path) -> None:
    """One line, naming the file, saying how to fix it."""
    text = str(exc)
    assert "\n" not in text and os.path.basename(str(path)) in text and "Fix:" in text, text
    assert len(text) < 600, text


def export(kind: str) -> bytes:
    buf = io.BytesIO()
    BOX.export(buf, file_type=kind)
    return buf.getvalue()


MESHES = {"stl": export("stl"), "ascii.stl": export("stl_ascii"), "obj": export("obj"),
          "ply": export("ply"), "ascii.ply": trimesh.exchange.ply.export_ply(BOX, encoding="ascii"),
          "off": export("off"),
          "glb": export("glb")}


def mutate(data: bytes, how: str, at: int, value: int) -> bytes:
    at = at % max(len(data), 1)
    if how == "truncate":
        return data[:at]
    if how == "flip":
        return data[:at] + bytes([data[at] ^ (value & 0xFF or 1)]) + data[at + 1:]
    if how == "count":  # a lying 32-bit count where a binary STL keeps its triangle count
        return data[:80] + struct.pack("<I", value) + data[84:]
    if how == "digits":  # a text count or coordinate blown up
        return data.replace(b"8", str(value).encode(), 1)
    return data


@FUZZ
@given(name=st.sampled_from(sorted(MESHES)),
       how=st.sampled_from(["truncate", "flip", "count", "digits", "none"]),
       at=st.integers(0, 10 ** 6), value=st.integers(0, 2 ** 32 - 1),
       wrap=st.sampled_from(["", ".gz", ".bz2", ".zip"]))
def test_mesh_files_read_right_or_refuse_in_one_line(tmp_path_factory, name, how, at, value,
                                                     wrap):
    data = mutate(MESHES[name], how, at, value)
    folder = tmp_path_factory.mktemp("mesh")
    plain = "mesh." + name.split(".")[-1]
    path = folder / (plain + (wrap if wrap != ".zip" else "")) if wrap != ".zip" else \
        folder / "mesh.zip"
    if wrap == ".gz":
        path.write_bytes(gzip.compress(data))
    elif wrap == ".bz2":
        path.write_bytes(bz2.compress(data))
    elif wrap == ".zip":
        with zipfile.ZipFile(path, "w") as z:
            z.writestr(plain, data)
    else:
        path.write_bytes(data)
    with budget():
        try:
            mesh = nl.load_mesh(path)
        except InputError as exc:
            refused_well(exc, path)
            return
    assert len(mesh.faces) >= 1 and np.all(np.isfinite(mesh.vertices))
    if how == "none":
        assert len(mesh.faces) == 12 and np.allclose(mesh.extents, BOX.extents)


def mat_bytes(value, compressed: bool) -> bytes:
    buf = io.BytesIO()
    scipy.io.savemat(buf, {"rect_data": value, "width": [[0.3]]}, do_compression=compressed)
    return buf.getvalue()


@FUZZ
@given(dtype=st.sampled_from(["f8", "f4", "i2", "u1", "c16", "bool"]),
       shape=st.sampled_from([(2, 2, 3), (1, 1, 1), (0, 2, 3), (2, 3)]),
       compressed=st.booleans(), how=st.sampled_from(["truncate", "flip", "none"]),
       at=st.integers(0, 4000), value=st.integers(1, 255))
def test_mat_v5_reads_right_or_refuses_in_one_line(tmp_path_factory, dtype, shape, compressed,
                                                   how, at, value):
    array = (np.arange(int(np.prod(shape))).reshape(shape) % 7).astype(dtype)
    raw = mat_bytes(array, compressed)
    if how != "none":
        at = 128 + at % max(len(raw) - 128, 1)  # past the text header: the tags and data
    path = tmp_path_factory.mktemp("mat") / "scan.mat"
    path.write_bytes(mutate(raw, how, at, value))
    with budget():
        try:
            got = load(path, "rect_data", 3)
        except InputError as exc:
            refused_well(exc, path)
            return
    assert got.dtype == np.float64 and got.ndim == 3 and np.all(np.isfinite(got))
    if how == "none":
        assert dtype != "c16" and np.array_equal(got, array.reshape(got.shape).astype(float))


def npy(value) -> bytes:
    buf = io.BytesIO()
    np.save(buf, value)
    return buf.getvalue()


@FUZZ
@given(hists=st.sampled_from(["good", "text", "3d", "nan", "huge-header", "raw"]),
       extra=st.sampled_from(["", "hists", "pt_cloud", "hists.npy"]),
       how=st.sampled_from(["truncate", "flip", "none"]), at=st.integers(0, 20000),
       value=st.integers(1, 255))
def test_npz_frames_read_right_or_refuse_in_one_line(tmp_path_factory, hists, extra, how, at,
                                                     value):
    members = {"pt_cloud.npy": npy(np.zeros((16, 3))),
               "hists.npy": {"good": npy(np.ones((16, 128))),
                             "text": npy(np.array(["a"] * 16 * 128).reshape(16, 128)),
                             "3d": npy(np.ones((16, 128, 2))),
                             "nan": npy(np.full((16, 128), np.nan)),
                             "huge-header": npy(np.ones((16, 128))).replace(
                                 b"(16, 128)", b"(16, 99999999999)", 1),
                             "raw": b"\0" * 512}[hists]}
    if extra:
        members[extra] = b"shadow"  # a raw member beside, or over, the checked one
    folder = tmp_path_factory.mktemp("npz")
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name, data in members.items():
            z.writestr(name, data)
    path = folder / "volume_000000.npz"
    path.write_bytes(mutate(buf.getvalue(), how, at, value))
    with budget():
        try:
            frames, _ = nl.read_dataset(folder, "consumer-nlos")
        except InputError as exc:
            refused_well(exc, folder)
            return
    assert hists == "good" and len(frames) == 1
    assert np.array_equal(frames[0][1].data, np.ones((16, 128)))


number = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=32),
                   st.integers(-10 ** 6, 10 ** 6)).map(str)
cell = st.one_of(number, st.sampled_from(["path", "time (s)", "2.5m", "5e-8x", "", "nan",
                                          "1,5", "µs"]))


@FUZZ
@given(rows=st.lists(st.lists(cell, min_size=1, max_size=3), min_size=0, max_size=6),
       sep=st.sampled_from([",", ";", "\t", " "]), unit=st.sampled_from([1.0, 1e9, 1e-3]))
def test_calibration_csv_reads_right_or_refuses_in_one_line(tmp_path_factory, rows, sep, unit):
    path = tmp_path_factory.mktemp("csv") / "pairs.csv"
    path.write_text("\n".join(sep.join(r) for r in rows) + "\n", "utf-8")
    try:
        paths, times = read_calibration_pairs(path)
    except InputError as exc:
        refused_well(exc, path)
        return
    assert paths.shape == times.shape and paths.size >= 1
    try:
        fit = nl.fit_calibration(paths, times * unit)
    except InputError as exc:  # too few pairs, NaN, a slope not c: named, one line
        assert "\n" not in str(exc) and "calibration pairs" in str(exc)
        return
    assert 1 / 1.5 <= fit.calibration.a_m_per_s / nl.SPEED_OF_LIGHT <= 1.5
