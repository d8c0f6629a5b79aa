"""Issue 59, class 1: what a file read from outside declares or expands to is checked against the
memory budget before it is allocated, whatever the container (compressed and archived meshes,
sparse glTF/OBJ buffers, a .mat v5 element declaring gigabytes, an .npz member shadowing the
checked one, a sequence declaring 10^9 frames), and only regular files are opened (a mesh's
assets too). Inputs that would have allocated gigabytes run in a child under an address-space
limit, so the old code fails them with a MemoryError instead of taking the machine."""
import bz2
import gzip
import io
import json
import lzma
import os
import signal
import struct
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io
import trimesh

import nlos_cl as nl
from nlos_cl.core.errors import InputError

ROOT = Path(__file__).resolve().parents[2]
BOX = trimesh.creation.box((0.3, 0.3, 1.6))


@pytest.fixture
def small_budget(monkeypatch):
    monkeypatch.setenv("NLOS_CL_MEMORY_LIMIT", "64M")  # a mesh may then hold 8 MiB


@pytest.fixture
def no_hang():
    """Fail (not hang) a test whose reader blocks on a FIFO."""
    def boom(*_):
        raise TimeoutError("the reader blocked")
    old = signal.signal(signal.SIGALRM, boom)
    signal.alarm(20)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, old)


def limited(code: str, limit=2 << 30, timeout=60) -> subprocess.CompletedProcess:
    """Run `code` in a child Python under an address-space limit."""
    pre = f"import resource; resource.setrlimit(resource.RLIMIT_AS, ({limit}, {limit}))\n"
    return subprocess.run([sys.executable, "-c", pre + textwrap.dedent(code)], check=False,
                          cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)))


def stl_of_zeros(n: int) -> bytes:
    return b"\0" * 80 + struct.pack("<I", n) + b"\0" * (50 * n)


COMPRESS = {"bz2": bz2.compress, "gz": gzip.compress, "xz": lzma.compress}


@pytest.mark.parametrize("suffix", sorted(COMPRESS))
def test_a_compressed_mesh_bomb_is_refused_before_it_is_inflated(tmp_path, small_budget, suffix):
    path = tmp_path / f"bomb.stl.{suffix}"
    path.write_bytes(COMPRESS[suffix](stl_of_zeros(400_000)))  # 20 MB from ~20 kB
    with pytest.raises(InputError, match=r"bomb\.stl\..*: decompresses to more than the 8 MiB"):
        nl.load_mesh(path)


@pytest.mark.parametrize("suffix", sorted(COMPRESS))
def test_compressed_meshes_within_the_budget_read_whole(tmp_path, suffix):
    raw = io.BytesIO()
    BOX.export(raw, file_type="stl")
    (tmp_path / f"box.stl.{suffix}").write_bytes(COMPRESS[suffix](raw.getvalue()))
    mesh = nl.load_mesh(tmp_path / f"box.stl.{suffix}")
    assert len(mesh.faces) == 12 and np.allclose(mesh.extents, BOX.extents)


def test_a_zip_declaring_more_than_the_budget_is_refused_unread(tmp_path, small_budget):
    with zipfile.ZipFile(tmp_path / "m.zip", "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("big.stl", stl_of_zeros(400_000))
    with pytest.raises(InputError, match=r"m\.zip: declares 19.07 MiB of members"):
        nl.load_mesh(tmp_path / "m.zip")


def test_a_zip_holding_one_mesh_reads_it(tmp_path):
    with zipfile.ZipFile(tmp_path / "m.zip", "w") as z:
        z.writestr("box.obj", trimesh.exchange.obj.export_obj(BOX))
        z.writestr("readme.txt", "a box")
    assert len(nl.load_mesh(tmp_path / "m.zip").faces) == 12


@pytest.mark.parametrize("suffix", ["obj", "stl", "ply", "glb"])
def test_a_sparse_mesh_file_past_the_budget_is_refused_by_its_size(tmp_path, small_budget,
                                                                   suffix):
    path = tmp_path / f"sparse.{suffix}"
    with open(path, "wb") as fh:
        fh.truncate(3 << 30)  # 3 GiB of holes: no disk used
    with pytest.raises(InputError, match=r"sparse\.\w+: is 3072 MiB, more than the 8 MiB"):
        nl.load_mesh(path)


def gltf(tmp_path, buffer_uri="box.bin", byte_length=None, accessors=None):
    data = np.asarray(BOX.vertices, np.float32).tobytes() + \
        np.asarray(BOX.faces, np.uint32).tobytes()
    n_v = len(BOX.vertices) * 12
    doc = {"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
           "buffers": [{"uri": buffer_uri, "byteLength": byte_length or len(data)}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": n_v},
                           {"buffer": 0, "byteOffset": n_v, "byteLength": len(data) - n_v}],
           "accessors": accessors or [
               {"bufferView": 0, "componentType": 5126, "count": len(BOX.vertices),
                "type": "VEC3", "min": BOX.bounds[0].tolist(), "max": BOX.bounds[1].tolist()},
               {"bufferView": 1, "componentType": 5125, "count": BOX.faces.size,
                "type": "SCALAR"}]}
    (tmp_path / "m.gltf").write_text(json.dumps(doc))
    return tmp_path / "m.gltf", data


def test_a_gltf_and_its_buffer_read_whole(tmp_path):
    path, data = gltf(tmp_path)
    (tmp_path / "box.bin").write_bytes(data)
    assert len(nl.load_mesh(path).faces) == 12


def test_a_gltf_buffer_that_is_a_fifo_is_refused_not_read(tmp_path, no_hang):
    path, _ = gltf(tmp_path)
    os.mkfifo(tmp_path / "box.bin")
    with pytest.raises(InputError, match=r"asset 'box\.bin': is a FIFO \(named pipe\), not a "
                       "regular file"):
        nl.load_mesh(path)


def test_a_gltf_buffer_past_the_budget_is_refused(tmp_path, small_budget):
    path, _ = gltf(tmp_path, byte_length=3 << 30)
    with open(tmp_path / "box.bin", "wb") as fh:
        fh.truncate(3 << 30)
    with pytest.raises(InputError, match=r"m\.gltf: declares 3072 MiB of buffers"):
        nl.load_mesh(path)


def test_a_gltf_accessor_declaring_a_billion_items_is_refused(tmp_path, small_budget):
    path, data = gltf(tmp_path, accessors=[
        {"componentType": 5126, "count": 10 ** 9, "type": "VEC3"},
        {"bufferView": 1, "componentType": 5125, "count": 36, "type": "SCALAR"}])
    (tmp_path / "box.bin").write_bytes(data)
    with pytest.raises(InputError, match=r"declares 1.144e\+04 MiB of buffers and accessors"):
        nl.load_mesh(path)


def test_a_gltf_buffer_outside_the_mesh_folder_is_not_read(tmp_path):
    (tmp_path / "in").mkdir()
    path, data = gltf(tmp_path / "in", buffer_uri="../box.bin")
    (tmp_path / "box.bin").write_bytes(data)
    with pytest.raises(InputError, match=r"asset '\.\./box\.bin': lies outside the mesh's "
                       "folder"):
        nl.load_mesh(path)


def test_an_obj_naming_a_fifo_as_its_mtllib_reads_without_it(tmp_path, no_hang):
    os.mkfifo(tmp_path / "m.mtl")
    (tmp_path / "m.obj").write_text("mtllib m.mtl\n" + trimesh.exchange.obj.export_obj(BOX))
    assert len(nl.load_mesh(tmp_path / "m.obj").faces) == 12


def test_a_mesh_file_that_is_a_fifo_is_refused(tmp_path, no_hang):
    os.mkfifo(tmp_path / "m.stl")
    with pytest.raises(InputError, match=r"m\.stl: is a FIFO"):
        nl.load_mesh(tmp_path / "m.stl")


def mat_declaring(path: Path, declared: int, compressed: bool) -> Path:
    """A v5 .mat whose 2 x 2 x 3 rect_data's data element declares `declared` bytes."""
    buf = io.BytesIO()
    scipy.io.savemat(buf, {"rect_data": np.ones((2, 2, 3)), "width": np.array([[0.3]])},
                     do_compression=False)
    raw = buf.getvalue()
    at = raw.index(struct.pack("<II", 9, 96), 128)  # miDOUBLE, 12 values
    raw = raw[:at] + struct.pack("<II", 9, declared) + raw[at + 8:]
    if compressed:  # the first variable as one deflated element
        first = raw[128:]
        packed = __import__("zlib").compress(first)
        raw = raw[:128] + struct.pack("<II", 15, len(packed)) + packed
    path.write_bytes(raw)
    return path


@pytest.mark.parametrize("compressed", [True, False])
def test_a_mat_element_declaring_gigabytes_is_refused_before_scipy_allocates(tmp_path,
                                                                            compressed):
    path = mat_declaring(tmp_path / "scan.mat", 3_900_000_000, compressed)
    run = limited(f"""
        from nlos_cl.io.datasets.matfile import load
        from nlos_cl.core.errors import InputError
        try:
            load({str(path)!r}, "rect_data", 3)
        except InputError as exc:
            print("InputError:", exc)
        """)
    assert "rect_data: declares 3,900,000,000 bytes of data for a (2, 2, 3) array" in \
        run.stdout, run.stdout + run.stderr


def npz_with_members(path: Path, members: dict) -> Path:
    with zipfile.ZipFile(path, "w") as z:
        for name, data in members.items():
            z.writestr(name, data)
    return path


def npy(array) -> bytes:
    buf = io.BytesIO()
    np.save(buf, array)
    return buf.getvalue()


def test_an_npz_member_shadowing_the_checked_one_is_refused(tmp_path):
    folder = tmp_path / "cap"
    folder.mkdir()
    good = {"hists.npy": npy(np.ones((16, 128))), "pt_cloud.npy": npy(np.zeros((16, 3)))}
    npz_with_members(folder / "volume_000000.npz", {**good, "hists": b"\0" * 4096})
    with pytest.raises(InputError, match=r"volume_000000\.npz: hists: is held by 2 members "
                       r"\(hists\.npy, hists\)"):
        nl.read_dataset(folder, "consumer-nlos")


def test_an_npz_field_that_is_no_npy_array_is_refused(tmp_path):
    folder = tmp_path / "cap"
    folder.mkdir()
    npz_with_members(folder / "volume_000000.npz", {"hists": b"\0" * 4096,
                                                    "pt_cloud.npy": npy(np.zeros((16, 3)))})
    with pytest.raises(InputError, match=r"volume_000000\.npz: hists: is not a \.npy array"):
        nl.read_dataset(folder, "consumer-nlos")


def test_a_sequence_declaring_a_billion_frames_is_refused_at_the_reader(tmp_path):
    path = tmp_path / "seq.h5"
    nl.write_sequence(path, [(k / 10, _frame()) for k in range(3)])
    with h5py.File(path, "a") as f:
        shape = f["H"].shape[1:]
        for name in ("H", "frame_t_s"):
            del f[name]
        f.create_dataset("H", (10 ** 9,) + shape, np.float32, chunks=(1,) + shape)
        f.create_dataset("frame_t_s", (10 ** 9,), np.float64, chunks=(4096,))
    run = limited(f"""
        from nlos_cl.tracking import read_sequence
        from nlos_cl.core.errors import InputError
        try:
            read_sequence({str(path)!r})
        except InputError as exc:
            print("InputError:", exc)
        """)
    assert "H: 1,000,000,000 frames declared, more than the 1,000,000 allowed" in run.stdout, \
        run.stdout + run.stderr[-600:]


def _frame():
    spots = nl.paper_setup().detector_spots
    return nl.HistogramSet(np.ones((3, 50)), nl.TimeAxis(1e-8, 1e-10, 50), spots, [0, 0, 0],
                           nl.PathCalibration(nl.SPEED_OF_LIGHT, [0.0]))


def test_a_volume_frame_that_is_a_fifo_or_folder_is_refused_by_name(tmp_path, no_hang):
    folder = tmp_path / "cap"
    folder.mkdir()
    good = {"hists.npy": npy(np.ones((16, 128))), "pt_cloud.npy": npy(np.zeros((16, 3)))}
    npz_with_members(folder / "volume_000000.npz", good)
    os.mkfifo(folder / "volume_000001.npz")
    with pytest.raises(InputError, match=r"frame volume_000001\.npz: is a FIFO"):
        nl.read_dataset(folder, "consumer-nlos")
    os.unlink(folder / "volume_000001.npz")
    (folder / "volume_000002.npz").mkdir()
    with pytest.raises(InputError, match=r"frame volume_000002\.npz: is a folder"):
        nl.read_dataset(folder, "consumer-nlos")


def test_one_long_string_aliased_thousands_of_times_is_refused():
    """9,000 aliases of one 100 kB string are 9,000 nodes (under the node bound) but 900 MB
    of text once written out (study.json, an error message): text is bounded too."""
    from nlos_cl.io.yamlfile import load_text
    text = "a: &s " + "x" * 100_000 + "\nb: [" + ", ".join(["*s"] * 9000) + "]\n"
    with pytest.raises(InputError, match=r"study\.yaml: its aliases expand to more than 1 MiB "
                       "of text"):
        load_text(text, "study.yaml")
    assert load_text("a: &s [1, 2]\nb: *s\n", "x") == {"a": [1, 2], "b": [1, 2]}
