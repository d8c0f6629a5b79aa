"""The red team's reader inputs (issue 59, classes 1-4 at the readers): meshes, MATLAB files,
.npz frames, sequences, calibration CSVs and edited captures, each built in the case's sandbox
and run through `nlos-cl simulate`, `convert`, `track` or `calibrate`. redteam_cases.py adds
READER_CASES to its CASES."""
from __future__ import annotations

import bz2
import io
import json
import os
import struct
import zipfile
import zlib

import h5py
import numpy as np
import scipy.io
import trimesh

PAPER_MESH = """setup: {{laser_spot: [0, 0, 0], detector_spots: [[-0.5, 0, 0], [-1, 0, 0], [-1.5, 0, 0]]}}
targets: [{{shape: mesh, file: {file}, position: [4, 2, 0]}}]
facet_size_m: 0.05
time_axis: {{dt_s: 10e-12}}
"""
BOX = trimesh.creation.box((0.3, 0.3, 1.6))


def mesh_scene(box, file: str):
    return box.text("scene.yaml", PAPER_MESH.format(file=file))


def exported(kind: str) -> bytes:
    buf = io.BytesIO()
    BOX.export(buf, file_type=kind)
    return buf.getvalue()


def bz2_bomb(box, name="bomb.stl.bz2", n=12_000_000):
    """A binary STL of n zero triangles (600 MB for the default), bz2-compressed (~ 1 kB)."""
    engine = bz2.BZ2Compressor(9)
    out = [engine.compress(b"\0" * 80 + struct.pack("<I", n))]
    block = b"\0" * (50 << 20)
    left = 50 * n
    while left > 0:
        out.append(engine.compress(block[:min(left, len(block))]))
        left -= len(block)
    (box.work / name).write_bytes(b"".join(out) + engine.flush())
    return name


def zip_declaring(box, name="big.zip", declared=0xFFFFFF00):
    """A zip whose one STL member declares ~4 GiB (its headers patched; the data is a box)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("big.stl", exported("stl"))
    raw = bytearray(buf.getvalue())
    size = len(exported("stl"))
    for sig, off in ((b"PK\x03\x04", 22), (b"PK\x01\x02", 24)):  # local, central header
        at = raw.index(sig)
        assert struct.unpack_from("<I", raw, at + off)[0] == size
        struct.pack_into("<I", raw, at + off, declared)
    (box.work / name).write_bytes(bytes(raw))
    return name


def sparse(box, name, size=3 << 30, head=b""):
    with open(box.work / name, "wb") as fh:
        fh.write(head)
        fh.truncate(size)
    return name


def gltf(box, buffer="box.bin", byte_length=None, fifo=False, sparse_bytes=0):
    data = np.asarray(BOX.vertices, np.float32).tobytes() + \
        np.asarray(BOX.faces, np.uint32).tobytes()
    n_v = len(BOX.vertices) * 12
    doc = {"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
           "buffers": [{"uri": buffer, "byteLength": byte_length or len(data)}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": n_v},
                           {"buffer": 0, "byteOffset": n_v, "byteLength": len(data) - n_v}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(BOX.vertices),
                          "type": "VEC3"},
                         {"bufferView": 1, "componentType": 5125, "count": BOX.faces.size,
                          "type": "SCALAR"}]}
    (box.work / "m.gltf").write_text(json.dumps(doc))
    if fifo:
        os.mkfifo(box.work / buffer)
    elif sparse_bytes:
        sparse(box, buffer, sparse_bytes, data)
    else:
        (box.work / buffer).write_bytes(data)
    return "m.gltf"


def fifo(box, name):
    os.mkfifo(box.work / name)
    return name


def obj_with_fifo_mtl(box):
    fifo(box, "m.mtl")
    (box.work / "m.obj").write_text("mtllib m.mtl\n" + trimesh.exchange.obj.export_obj(BOX))
    return "m.obj"


def cut(box, name, data: bytes, at):
    (box.work / name).write_bytes(data[:at])
    return name


def mat73(path, variables, attrs=None):
    with h5py.File(path, "w", userblock_size=512) as f:
        for name, value in variables.items():
            if isinstance(value, dict):  # a group: MATLAB's sparse storage
                g = f.create_group(name)
                for k, v in value.items():
                    g[k] = v
                g.attrs["MATLAB_class"], g.attrs["MATLAB_sparse"] = np.bytes_(b"double"), 64
                continue
            f[name] = value
            f[name].attrs["MATLAB_class"] = np.bytes_(b"double")
    with open(path, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".ljust(116)
                 + bytes(8) + b"\x00\x02IM")
    return path


def keyhole(box, data):
    folder = box.work / "K"
    folder.mkdir()
    direct = np.zeros(2000)
    direct[600:620] = np.linspace(10, 1000, 20)
    mat73(folder / "direct_after.mat", {"direct_after": direct[None, :]})
    mat73(folder / "LongExpNoObject_after.mat", {"LongExpNoObject_after": np.ones((1, 2000))})
    n = data.shape[0] if data.ndim else 1
    mat73(folder / "scan_0.mat", {"data": data, "xpos": np.zeros((1, n)),
                                  "zpos": np.zeros((1, n))})
    return folder


def v5(values, compressed=False) -> bytes:
    buf = io.BytesIO()
    scipy.io.savemat(buf, values, do_compression=compressed)
    return buf.getvalue()


def mat_declaring(box, declared=3_900_000_000):
    """rect_data (2, 2, 3) whose data element declares `declared` bytes, zlib-compressed."""
    raw = v5({"rect_data": np.ones((2, 2, 3))})
    at = raw.index(struct.pack("<II", 9, 96), 128)
    first = raw[128:at] + struct.pack("<II", 9, declared) + raw[at + 8:]
    packed = zlib.compress(first)
    head = v5({"width": [[0.3]]})
    (box.work / "scan.mat").write_bytes(raw[:128] + struct.pack("<II", 15, len(packed)) + packed
                                        + head[128:])
    return box.work / "scan.mat"


def mat_flipped(box, at, flip):
    raw = bytearray(v5({"rect_data": np.arange(12.0).reshape(2, 2, 3), "width": [[0.3]]}))
    raw[at] ^= flip
    (box.work / "scan.mat").write_bytes(bytes(raw))
    return box.work / "scan.mat"


def npy(value) -> bytes:
    buf = io.BytesIO()
    np.save(buf, value)
    return buf.getvalue()


def volumes(box, shadow=False, fifo_frame=False):
    folder = box.work / "walk"
    folder.mkdir()
    for k in range(3):
        members = {"hists.npy": npy(np.ones((16, 128))), "pt_cloud.npy": npy(np.zeros((16, 3)))}
        if shadow:  # a raw member np.load would read in place of the checked hists.npy
            members["hists"] = b"\0" * (1 << 20)
        with zipfile.ZipFile(folder / f"volume_{k:06d}.npz", "w") as z:
            for name, data in members.items():
                z.writestr(name, data)
    if fifo_frame:
        os.unlink(folder / "volume_000001.npz")
        os.mkfifo(folder / "volume_000001.npz")
    return folder


def fk(box, tof_scale=1.0, z_offset=None):
    folder = box.work / "fk"
    folder.mkdir()
    meas = np.zeros((8, 8, 600))
    meas[..., 300] = 5.0
    scipy.io.savemat(folder / "meas_10min.mat", {"meas": meas})
    scipy.io.savemat(folder / "tof.mat", {"tofgrid": np.full((8, 8), 4000.0) * tof_scale})
    if z_offset is not None:
        scipy.io.savemat(folder / "calibration.mat", {"z_offset": np.full((8, 8), z_offset),
                                                      "width": [[1.0]]})
    return folder


def billion_frames(box):
    path = box.copy("seq.h5", "big.h5")
    with h5py.File(path, "a") as f:
        shape = f["H"].shape[1:]
        for name in ("H", "frame_t_s"):
            del f[name]
        f.create_dataset("H", (10 ** 9,) + shape, np.float32, chunks=(1,) + shape)
        f.create_dataset("frame_t_s", (10 ** 9,), np.float64, chunks=(4096,))
    return path


def ours_then_edited(box, name, edit):
    """A capture nlos_cl wrote here (its manifest entry, as the writer records it), then
    changed by the user."""
    from nlos_cl.io.safe_write import record
    path = box.copy(name)
    record(path)
    with h5py.File(path, "a") as f:
        edit(f)
    return path


def measured(f):
    f["H"][...] = np.random.default_rng(0).poisson(3, f["H"].shape).astype(f["H"].dtype)


def added(f):
    f["my_dark_counts"] = np.arange(100.0)
