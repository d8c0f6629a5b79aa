"""The red team's inputs by other routes (issue 59, "a private set of other hostile inputs of
the same classes, by other routes"): the classes of the catalogue reached through containers,
commands, fields and path options it did not try: gzip/xz/tar meshes, GLB chunks, glTF
assets and URIs, HDF5 attributes, filters and virtual datasets in captures and MATLAB v7.3
files, f-k and Keyhole files, FIFOs and devices in every path option, units of each dataset
reader's fields and options, nlos_cl outputs the user edited, and the Python API
(redteam_api.py). redteam_cases.py adds ROUTE_CASES to its CASES."""
from __future__ import annotations

import gzip
import io
import lzma
import os
import struct
import tarfile
import zlib

import h5py
import numpy as np
import redteam_readers as R
import scipy.io
from redteam_cases import (
    DL,
    HANG,
    LOC,
    MEM,
    SEC,
    SWEEP0,
    TB,
    VAGUE,
    WRONG,
    Case,
    edited_capture,
    located_within,
    says,
)

OUT = ["--out", "o.h5"]
UNITS = says("millimet", "unit", " mm", "nanosec")


def gz_stl(box, n=12_000_000):
    """A binary STL of n zero triangles (600 MB), gzip-compressed (~600 kB)."""
    engine = zlib.compressobj(9, zlib.DEFLATED, 31)
    parts = [engine.compress(b"\0" * 80 + struct.pack("<I", n))]
    block = bytes(50 << 20)
    for _ in range(n * 50 // len(block)):
        parts.append(engine.compress(block))
    parts.append(engine.compress(bytes(n * 50 % len(block))))
    (box.work / "m.stl.gz").write_bytes(b"".join(parts) + engine.flush())
    return "m.stl.gz"


def xz_obj(box, lines=40_000_000):
    """An OBJ of `lines` vertex lines (320 MB of text), xz-compressed (~50 kB)."""
    engine = lzma.LZMACompressor(preset=1)
    block = b"v 0 0 0\n" * (1 << 20)
    parts = [engine.compress(block) for _ in range(lines >> 20)]
    (box.work / "m.obj.xz").write_bytes(b"".join(parts) + engine.flush())
    return "m.obj.xz"


def tar_link(box, target):
    """A .tar.gz whose one member m.stl is a symlink to `target`."""
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w:gz") as t:
        info = tarfile.TarInfo("m.stl")
        info.type, info.linkname = tarfile.SYMTYPE, str(target)
        t.addfile(info)
    (box.work / "m.tar.gz").write_bytes(buf.getvalue())
    return "m.tar.gz"


def glb_declaring(box, count=1_000_000_000):
    """A GLB whose embedded JSON declares an accessor of `count` VEC3 floats (12 GB)."""
    doc = (b'{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],'
           b'"accessors":[{"componentType":5126,"count":%d,"type":"VEC3"}],"nodes":[{"mesh":0}],'
           b'"scenes":[{"nodes":[0]}]}' % count)
    doc += b" " * (-len(doc) % 4)
    body = struct.pack("<II", len(doc), 0x4E4F534A) + doc
    (box.work / "m.glb").write_bytes(b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body)
    return "m.glb"


def gltf_uri(box, uri, image=False):
    """R.gltf's box, its buffer (or an image, with the buffer beside it) named by `uri`."""
    name = R.gltf(box)
    if image:
        text = (box.work / name).read_text()
        (box.work / name).write_text(text[:-1] + f', "images": [{{"uri": "{uri}"}}]}}')
    else:
        text = (box.work / name).read_text().replace('"box.bin"', f'"{uri}"')
        (box.work / name).write_text(text)
    return name


def linked_buffer(box):
    name = R.gltf(box, buffer="b.bin")
    (box.work / "b.bin").unlink()
    (box.work / "b.bin").symlink_to(box.outside / "secret.txt")
    return name


def obj_mtllib(box, target):
    (box.work / "m.obj").write_text(f"mtllib {target}\n" + R.trimesh.exchange.obj.export_obj(
        R.BOX))
    return "m.obj"


def mat73_attr(box, value):
    """A v7.3 LCT file whose rect_data's MATLAB_class attribute is `value`."""
    path = box.work / "a.mat"
    with h5py.File(path, "w", userblock_size=512, libver="latest") as f:  # attributes: any size
        f["rect_data"], f["width"] = np.ones((64, 4, 4)), np.array([[0.3]])
        f["width"].attrs["MATLAB_class"] = np.bytes_(b"double")
        f["rect_data"].attrs["MATLAB_class"] = value
    with open(path, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, HDF5 schema 1.00 .".ljust(116) + bytes(8) + b"\x00\x02IM")
    return path


def mat73_filter(box, filter_id=32001):
    """A v7.3 LCT file whose rect_data's one chunk is marked compressed with an HDF5 filter
    plugin (blosc's id by default) that h5py does not ship."""
    path = R.mat73(box.work / "f.mat", {"width": np.array([[0.3]])})
    with h5py.File(path, "r+") as f:
        dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
        dcpl.set_chunk((64, 4, 4))
        dcpl.set_filter(filter_id, h5py.h5z.FLAG_OPTIONAL, (2, 2, 4, 1024))
        space = h5py.h5s.create_simple((64, 4, 4))
        dsid = h5py.h5d.create(f.id, b"rect_data", h5py.h5t.IEEE_F64LE, space, dcpl=dcpl)
        dsid.write_direct_chunk((0, 0, 0), zlib.compress(bytes(64 * 16 * 8)), filter_mask=0)
        f["rect_data"].attrs["MATLAB_class"] = np.bytes_(b"double")
    return path


def mat73_virtual(box):
    """A v7.3 LCT file whose rect_data is a virtual dataset mapped from a file outside."""
    with h5py.File(box.outside / "cube.h5", "w") as o:
        o["c"] = np.ones((64, 4, 4))
    path = R.mat73(box.work / "v.mat", {"width": np.array([[0.3]])})
    layout = h5py.VirtualLayout((64, 4, 4), np.float64)
    layout[...] = h5py.VirtualSource(str(box.outside / "cube.h5"), "c", (64, 4, 4))
    with h5py.File(path, "r+") as f:
        f.create_virtual_dataset("rect_data", layout)
        f["rect_data"].attrs["MATLAB_class"] = np.bytes_(b"double")
    return path


def bomb_chunk(d, inflated=3 << 30):
    """Chunk 0 of `d` as one deflate stream of `inflated` zero bytes (~3 MB stored)."""
    engine, block, parts = zlib.compressobj(9), bytes(64 << 20), []
    for _ in range(inflated // len(block)):
        parts.append(engine.compress(block))
    d.id.write_direct_chunk((0,) * d.ndim, b"".join(parts) + engine.flush(), filter_mask=0)


def fk73_bomb(box):
    """An f-k folder whose v7.3 meas's one deflate chunk inflates to 3 GiB."""
    folder = box.work / "fk"
    folder.mkdir()
    path = R.mat73(folder / "meas_10min.mat", {})
    with h5py.File(path, "r+") as f:
        d = f.create_dataset("meas", (600, 8, 8), np.float64, chunks=(600, 8, 8),
                             compression="gzip")
        d.attrs["MATLAB_class"] = np.bytes_(b"double")
        bomb_chunk(d)
    scipy.io.savemat(folder / "tof.mat", {"tofgrid": np.full((8, 8), 4000.0)})
    return folder


def keyhole_bomb(box):
    folder = R.keyhole(box, np.zeros((3, 2000)))
    with h5py.File(folder / "scan_0.mat", "r+") as f:
        del f["data"]
        d = f.create_dataset("data", (2000, 3), np.float64, chunks=(2000, 3),
                             compression="gzip")
        d.attrs["MATLAB_class"] = np.bytes_(b"double")
        bomb_chunk(d)
    return folder


def capture_virtual(box):
    with h5py.File(box.outside / "other.h5", "w") as o:
        o["H"] = np.zeros((6005, 3), np.float32)

    def edit(f):
        shape = f["H"].shape
        del f["H"]
        layout = h5py.VirtualLayout(shape, np.float32)
        layout[...] = h5py.VirtualSource(str(box.outside / "other.h5"), "H", shape)
        f.create_virtual_dataset("H", layout)
    return edited_capture(box, edit, "vds.h5")


def capture_filter(box, filter_id=32015):
    """A capture whose H is chunked through a filter plugin (zstd's id) h5py lacks."""
    def edit(f):
        data = f["H"][()]
        del f["H"]
        dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
        dcpl.set_chunk(data.shape)
        dcpl.set_filter(filter_id, h5py.h5z.FLAG_OPTIONAL, (3,))
        space = h5py.h5s.create_simple(data.shape)
        dsid = h5py.h5d.create(f.id, b"H", h5py.h5t.IEEE_F32LE, space, dcpl=dcpl)
        dsid.write_direct_chunk((0, 0), data.tobytes(), filter_mask=0)
    return edited_capture(box, edit, "zstd.h5")


def big_attribute(box, n=40_000_000):
    """A capture whose root carries a 160 MB attribute (dense attribute storage)."""
    path = latest(box, "attr.h5")
    with h5py.File(path, "r+", libver="latest") as f:
        f.attrs.create("notes", np.zeros(n, np.float32))
    return path


def latest(box, name):
    """The capture fixture copied into a file of HDF5's latest format (dense attributes)."""
    path = box.work / name
    with h5py.File(box.fixtures.path("cap.h5"), "r") as a, \
            h5py.File(path, "w", libver="latest") as b:
        for key in a:
            a.copy(a[key], b, name=key)
        b.attrs.update(a.attrs)
    return path


def many_attributes(box, n=120_000):
    path = latest(box, "attrs.h5")
    with h5py.File(path, "r+", libver="latest") as f:  # dense attribute storage: quick
        for i in range(n):
            f.attrs.create(f"a{i}", i)
    return path


def v5_many(box, n=1_000_000):
    """A v5 .mat of `n` one-value variables before rect_data and width (~60 MB)."""
    raw = R.v5({"x": [[1.0]]})
    one = raw[128:]
    body = R.v5({"rect_data": np.ones((2, 2, 3)), "width": [[0.3]]})
    (box.work / "many.mat").write_bytes(body[:128] + one * n + body[128:])
    return box.work / "many.mat"


def fifo(box, name):
    path = box.work / name
    path.parent.mkdir(parents=True, exist_ok=True)
    os.mkfifo(path)
    return path


def devlink(box, name, target="/dev/zero"):
    (box.work / name).symlink_to(target)
    return box.work / name


def ccsocr(box, grid=None):
    folder = box.work / "cc"
    folder.mkdir()
    sig = np.zeros((4, 512))
    sig[:, 200] = 10.0
    scipy.io.savemat(folder / "sub_Sig.mat", {"sub_Sig": sig})
    pts = np.array([[0, 10, 0], [0, 20, 0], [0, 30, 0], [0, 40, 0]], float)
    scipy.io.savemat(folder / "C_i.mat", {"C_i": pts})
    scipy.io.savemat(folder / "C_d.mat", {"C_d": pts + [0, 0, 10]})
    return folder


def lct(box, width=0.35):
    cube = np.zeros((8, 8, 512))
    cube[..., 300] = 5.0
    scipy.io.savemat(box.work / "rect.mat", {"rect_data": cube, "width": [[width]]})
    return box.work / "rect.mat"


def consumer_mm(box):
    """consumer-nlos frames whose pt_cloud is in millimetres (their wall spans 1 m)."""
    folder = box.work / "walk"
    folder.mkdir()
    g = np.linspace(-0.5, 0.5, 4)
    x, y = np.meshgrid(g, g)
    cloud = np.column_stack([x.ravel(), y.ravel(), np.zeros(16)]) * 1000.0
    hists = np.zeros((16, 128))
    hists[:, 60] = 5.0
    for k in range(3):
        np.savez(folder / f"volume_{k:06d}.npz", hists=hists, pt_cloud=cloud)
    return folder


def keyhole_mm(box):
    folder = R.keyhole(box, np.ones((3, 2000)))
    with h5py.File(folder / "scan_0.mat", "r+") as f:
        for name in ("xpos", "zpos"):
            f[name][...] = 500.0  # the stage's 0.5 m, in millimetres
    return folder


def edited_map(box):
    """A map `locate --map` wrote here (its manifest entry), its scores then edited."""
    from nlos_cl.io.safe_write import record
    path = box.work / "m.npz"
    axis = np.linspace(0, 1, 3)
    np.savez(path, score=np.zeros((3, 3, 3)), x=axis, y=axis, z=axis)
    record(path)
    with np.load(path) as d:
        arrays = dict(d)
    arrays["score"][0, 0, 0] = 42.0  # the user's own annotation
    np.savez(path, **arrays)
    return path


def truncated_ours(box):
    """A capture nlos_cl wrote here whose copy was interrupted (half of it left)."""
    from nlos_cl.io.safe_write import record
    path = box.copy("cap.h5", "c.h5")
    record(path)
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    return path


def gz_capture(box):
    (box.work / "cap.h5.gz").write_bytes(gzip.compress(box.fixtures.path("cap.h5").read_bytes()))
    return box.work / "cap.h5.gz"


def _mesh_study(box, file):
    (box.work / "ms.yaml").write_text(
        "scene:\n  setup: {detector_spots: [[-0.5, 0, 0], [-1, 0, 0], [-1.5, 0, 0]]}\n"
        f"  targets: [{{shape: mesh, file: '{file}', position: [4, 2, 0]}}]\n"
        "  facet_size_m: 0.05\n  time_axis: {dt_s: 1.0e-11}\n"
        "axes: [{path: noise.snr_db, values: [10]}]\n")
    return "ms.yaml"


SIM = R.mesh_scene
ROUTE_CASES = [
    # ---- unbounded memory, by other containers and files
    Case(MEM, "a gzip STL bomb (600 MB of triangles) as a scene's mesh",
         lambda b: ["simulate", SIM(b, gz_stl(b)), *OUT]),
    Case(MEM, "an xz OBJ bomb (320 MB of vertex lines) as a scene's mesh",
         lambda b: ["simulate", SIM(b, xz_obj(b)), *OUT]),
    Case(MEM, "a GLB whose embedded JSON declares a 12 GB accessor",
         lambda b: ["simulate", SIM(b, glb_declaring(b)), *OUT]),
    Case(MEM, "an f-k v7.3 meas whose deflate chunk inflates to 3 GiB",
         lambda b: ["convert", fk73_bomb(b), *OUT]),
    Case(MEM, "a Keyhole v7.3 scan whose deflate chunk inflates to 3 GiB",
         lambda b: ["convert", keyhole_bomb(b), *OUT]),
    Case(MEM, "a v7.3 rect_data compressed with a filter plugin (blosc) h5py lacks",
         lambda b: ["convert", mat73_filter(b), "--format", "lct", *OUT]),
    Case(MEM, "a capture whose H is compressed with a filter plugin (zstd) h5py lacks",
         lambda b: ["locate", capture_filter(b), *LOC]),
    Case(MEM, "a capture carrying a 160 MB attribute",
         lambda b: ["locate", big_attribute(b), *LOC], ok=located_within(0.05)),
    Case(MEM, "a v7.3 rect_data whose MATLAB_class attribute is 10^6 numbers",
         lambda b: ["convert", mat73_attr(b, np.zeros(1_000_000)), "--format", "lct", *OUT]),
    Case(MEM, "a sparse 3 GiB scene file",
         lambda b: ["simulate", R.sparse(b, "big.yaml", head=b"description: x\n"), *OUT]),
    Case(MEM, "a 16 MiB calibration CSV on one line",
         lambda b: ["calibrate", b.text("pairs.csv", "2.5," * (4 << 20))]),
    Case(MEM, "locate --background /dev/zero (through a link)",
         lambda b: ["locate", b.copy("cap.h5"), *LOC, "--background", devlink(b, "bg.h5")]),
    # ---- hangs: FIFOs and devices in every path option
    Case(HANG, "locate --background a FIFO",
         lambda b: ["locate", b.copy("cap.h5"), *LOC, "--background", fifo(b, "bg.h5")]),
    Case(HANG, "track --background a FIFO",
         lambda b: ["track", b.copy("seq.h5"), "--background", fifo(b, "bg.h5"),
                    "--no-progress"]),
    Case(HANG, "locate --calibration a FIFO",
         lambda b: ["locate", b.copy("cap.h5"), *LOC, "--calibration", fifo(b, "c.json")]),
    Case(HANG, "calibrate on a FIFO", lambda b: ["calibrate", fifo(b, "pairs.csv")]),
    Case(HANG, "a scene file that is a FIFO", lambda b: ["simulate", fifo(b, "s.yaml"), *OUT]),
    Case(HANG, "a study file that is /dev/zero (through a link)",
         lambda b: ["sweep", devlink(b, "s.yaml"), "--out", b.work / "o", *SWEEP0]),
    Case(HANG, "a CC-SOCR folder whose sub_Sig.mat is a FIFO",
         lambda b: ["convert", _swap_fifo(ccsocr(b), "sub_Sig.mat"), *OUT]),
    Case(HANG, "an f-k folder whose tof.mat is a FIFO",
         lambda b: ["convert", _swap_fifo(R.fk(b), "tof.mat"), *OUT]),
    Case(HANG, "a Keyhole folder whose direct_after.mat is a FIFO",
         lambda b: ["convert", _swap_fifo(R.keyhole(b, np.ones((3, 2000))),
                                          "direct_after.mat"), *OUT]),
    Case(HANG, "convert --format lct of /dev/zero (through a link)",
         lambda b: ["convert", devlink(b, "z.mat"), "--format", "lct", *OUT]),
    Case(HANG, "a v5 .mat of 10^6 variables before rect_data",
         lambda b: ["convert", v5_many(b), "--format", "lct", *OUT],
         ok=lambda out, err: "o.h5" in out),
    Case(HANG, "a capture with 120,000 attributes on its root",
         lambda b: ["locate", many_attributes(b), *LOC], ok=located_within(0.05)),
    # ---- security: assets and storage that reach files outside
    Case(SEC, "a scene's mesh naming a text file outside (its content in an error?)",
         lambda b: ["simulate", SIM(b, str(b.outside / "secret.txt")), *OUT]),
    Case(SEC, "a study's scene mesh naming a text file outside",
         lambda b: ["sweep", b.work / _mesh_study(b, b.outside / "secret.txt"), "--out",
                    b.work / "o", *SWEEP0]),
    Case(SEC, "a glTF buffer that is a link to a file outside",
         lambda b: ["simulate", SIM(b, linked_buffer(b)), *OUT]),
    Case(SEC, "a glTF buffer named by a file:// URI outside",
         lambda b: ["simulate", SIM(b, gltf_uri(b, f"file://{b.outside}/secret.txt")), *OUT]),
    Case(SEC, "a glTF image URI to a file outside", lambda b: [
        "simulate", SIM(b, gltf_uri(b, "../outside/secret.txt", image=True)), *OUT],
        ok=says("wrote")),
    Case(SEC, "an OBJ whose mtllib names a file outside",
         lambda b: ["simulate", SIM(b, obj_mtllib(b, b.outside / "secret.txt")), *OUT],
         ok=says("wrote")),
    Case(SEC, "a mesh .tar.gz whose m.stl is a symlink to a file outside",
         lambda b: ["simulate", SIM(b, tar_link(b, b.outside / "secret.txt")), *OUT]),
    Case(SEC, "a v7.3 rect_data that is a virtual dataset of a file outside",
         lambda b: ["convert", mat73_virtual(b), "--format", "lct", *OUT]),
    Case(SEC, "a capture whose H is a virtual dataset of a file outside",
         lambda b: ["locate", capture_virtual(b), *LOC]),
    Case(SEC, "a consumer-nlos frame that is a link to a file outside",
         lambda b: ["convert", _link_frame(b), *OUT]),
    # ---- data loss: outputs the user edited, interrupted writes
    Case(DL, "locate --map over an nlos_cl map whose scores the user edited",
         lambda b: ["locate", b.copy("cap.h5"), *LOC, "--map", edited_map(b)]),
    Case(DL, "simulate --out over an nlos_cl capture whose copy was interrupted",
         lambda b: ["simulate", "--out", truncated_ours(b), "--facet", "0.05"]),
    Case(DL, "convert --out onto a link to the user's file",
         lambda b: ["convert", lct(b), "--format", "lct", "--out",
                    _link_to(b, "l.h5", b.text("mine.txt", "my notes\n"))]),
    # ---- silently wrong: units of each reader's fields and options
    Case(WRONG, "an LCT width in millimetres (350)",
         lambda b: ["convert", lct(b, width=350.0), *OUT], ok=UNITS),
    Case(WRONG, "convert lct --width 350 (millimetres)",
         lambda b: ["convert", lct(b), "--width", "350", *OUT], ok=UNITS),
    Case(WRONG, "convert lct --dt-ps 4e-12 (seconds)",
         lambda b: ["convert", lct(b), "--dt-ps", "4e-12", *OUT], ok=UNITS),
    Case(WRONG, "convert ccsocr --grid-m 10 (centimetres)",
         lambda b: ["convert", ccsocr(b), "--grid-m", "10", *OUT], ok=UNITS),
    Case(WRONG, "consumer-nlos pt_cloud in millimetres",
         lambda b: ["convert", consumer_mm(b), *OUT], ok=UNITS),
    Case(WRONG, "Keyhole stage positions in millimetres",
         lambda b: ["convert", keyhole_mm(b), *OUT], ok=UNITS),
    Case(WRONG, "a capture with its laser spot (0.2 m beside the origin) in millimetres",
         lambda b: ["locate", edited_capture(b, _moved_laser), *LOC]),
    Case(WRONG, "a calibration CSV with paths in millimetres",
         lambda b: ["calibrate", b.text("pairs.csv", "2500,8.34e-9\n3000,1.0e-8\n"
                                        "3500,1.17e-8\n4000,1.33e-8\n")], ok=UNITS),
    Case(WRONG, "a calibration CSV with times in nanoseconds",
         lambda b: ["calibrate", b.text("pairs.csv", "2.5,8.34\n3.0,10.0\n3.5,11.7\n"
                                        "4.0,13.3\n")], ok=UNITS),
    Case(WRONG, "a calibration CSV with a BOM, CRLF and a header (must work)",
         lambda b: ["calibrate", b.text("pairs.csv", "\ufeffpath,time\r\n2.5,8.34e-9\r\n"
                                        "3.0,1.0e-8\r\n3.5,1.17e-8\r\n4.0,1.33e-8\r\n")],
         ok=lambda out, err: "cm/ns" in out and "4 pairs" in out),
    # ---- tracebacks
    Case(TB, "a v7.3 rect_data whose MATLAB_class attribute is an array",
         lambda b: ["convert", mat73_attr(b, np.array([1.0, 2.0])), "--format", "lct", *OUT]),
    Case(TB, "a capture whose H holds object references",
         lambda b: ["locate", edited_capture(b, _refs), *LOC]),
    Case(TB, "nl.read_capture on a folder", lambda b: ["api", "read_capture", b.work]),
    Case(TB, "nl.read_dataset on a FIFO (format lct)",
         lambda b: ["api", "read_dataset", fifo(b, "x.mat"), 'format="lct"']),
    Case(TB, "nl.locate_capture on a gzip-compressed capture",
         lambda b: ["api", "locate_capture", gz_capture(b), 'estimator="paper"']),
    Case(TB, "nl.track_sequence on a text file",
         lambda b: ["api", "track_sequence", b.text("s.h5", "hello\n")]),
    # ---- vague
    Case(VAGUE, "locate on a gzip-compressed capture",
         lambda b: ["locate", gz_capture(b), *LOC]),
    Case(VAGUE, "convert of a gzip-compressed LCT .mat",
         lambda b: ["convert", _gz(lct(b)), "--format", "lct", *OUT]),
    Case(VAGUE, "info --device of 100 kB", lambda b: ["info", "--device", "d" * 100_000]),
]


def _moved_laser(f):
    value = (np.asarray(f["laser_grid_xyz"][()]) + [0.2, 0.0, 0.0]) * 1000.0
    del f["laser_grid_xyz"]
    f["laser_grid_xyz"] = value


def _refs(f):
    ref = f["sensor_grid_xyz"].ref
    shape = f["H"].shape
    del f["H"]
    f.create_dataset("H", shape, h5py.ref_dtype)[...] = ref


def _gz(path):
    out = path.with_name(path.name + ".gz")
    out.write_bytes(gzip.compress(path.read_bytes()))
    return out


def _swap_fifo(folder, name):
    (folder / name).unlink()
    os.mkfifo(folder / name)
    return folder


def _link_frame(box):
    folder = R.volumes(box)
    (folder / "volume_000001.npz").unlink()
    (folder / "volume_000001.npz").symlink_to(box.outside / "secret.txt")
    return folder


def _link_to(box, name, target):
    (box.work / name).symlink_to(target)
    return box.work / name
