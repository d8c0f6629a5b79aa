"""Issue 59, classes 2 and 3 at the readers: what used to end in a traceback (Keyhole scans with
no frames or scalar data, compound or sparse MATLAB storage, Ctrl-C during convert) is one line
naming the file and field; what used to be read silently wrong (f-k's tofgrid in ns, z_offset in
mm, a calibration CSV whose mistyped first row passed for a header, a mesh cut short) is refused
with the unit or the cut named."""
import io
import os
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io
import trimesh

import nlos_cl as nl
from nlos_cl.apps.cli import main as cli
from nlos_cl.core.errors import InputError
from nlos_cl.io.calibration import read_calibration_pairs

BOX = trimesh.creation.box((0.3, 0.3, 1.6))


def mat73(path, variables, attrs=None):
    """A MATLAB v7.3 file: a 512-byte header, then HDF5 (values stored as h5py gives them)."""
    with h5py.File(path, "w", userblock_size=512) as f:
        for name, value in variables.items():
            f[name] = value
            f[name].attrs["MATLAB_class"] = np.bytes_(b"double")
            for key, v in (attrs or {}).get(name, {}).items():
                f[name].attrs[key] = v
    with open(path, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".ljust(116)
                 + bytes(8) + b"\x00\x02IM")
    return path


def keyhole(tmp_path, data, bins=2000):
    folder = tmp_path / "K"
    folder.mkdir()
    direct = np.zeros(bins)
    direct[600:620] = np.linspace(10, 1000, 20)
    mat73(folder / "direct_after.mat", {"direct_after": direct[None, :]})
    mat73(folder / "LongExpNoObject_after.mat", {"LongExpNoObject_after": np.ones((1, bins))})
    n = data.shape[0] if data.ndim else 1
    mat73(folder / "scan_0.mat", {"data": data, "xpos": np.zeros((1, n)),
                                  "zpos": np.zeros((1, n))})
    return folder


@pytest.mark.parametrize("data, said", [
    (np.zeros((0, 2000)), r"data: is \(0, 2000\), expected \(frames, bins\)"),
    (np.float64(3.0), r"data: is \(\), expected \(frames, bins\)"),
    (np.zeros((2, 100)), (r"data: is \(2, 100\), expected \(frames, bins\): one histogram "
                          "of more than 768 bins"))])
def test_keyhole_scans_without_frames_or_bins_are_refused_by_name(tmp_path, data, said):
    folder = keyhole(tmp_path, data)
    with pytest.raises(InputError, match=r"scan_0\.mat: " + said):
        nl.read_dataset(folder, "keyhole")


def test_keyhole_scan_stored_as_matlab_empty_is_read_as_no_frames(tmp_path):
    folder = keyhole(tmp_path, np.zeros((1, 2000)))
    mat73(folder / "scan_0.mat", {"data": np.array([2000, 0], np.uint64), "xpos": np.zeros(1),
                                  "zpos": np.zeros(1)}, {"data": {"MATLAB_empty": 1}})
    with pytest.raises(InputError, match=r"scan_0\.mat: data: is \(0, 2000\)"):
        nl.read_dataset(folder, "keyhole")


def test_compound_and_sparse_matlab_storage_is_named(tmp_path):
    cplx = np.zeros((2, 3, 4), dtype=[("real", "<f8"), ("imag", "<f8")])
    path = mat73(tmp_path / "c.mat", {"rect_data": cplx, "width": np.array([[0.3]])})
    with pytest.raises(InputError, match=r"c\.mat: rect_data: is declared complex"):
        nl.read_dataset(path, "lct")
    v5 = tmp_path / "s.mat"
    scipy.io.savemat(v5, {"rect_data": np.zeros((2, 2, 3)) + 1j, "width": [[0.3]]})
    with pytest.raises(InputError, match=r"s\.mat: rect_data: holds complex numbers"):
        nl.read_dataset(v5, "lct")
    sparse = tmp_path / "sp.mat"
    with h5py.File(sparse, "w", userblock_size=512) as f:
        g = f.create_group("rect_data")
        g.attrs["MATLAB_class"], g.attrs["MATLAB_sparse"] = np.bytes_(b"double"), 64
        g["jc"] = np.zeros(65, np.uint64)
        f["width"] = np.array([[0.3]])
        f["width"].attrs["MATLAB_class"] = np.bytes_(b"double")
    with open(sparse, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file".ljust(116) + bytes(8) + b"\x00\x02IM")
    with pytest.raises(InputError, match=r"sp\.mat: rect_data: is declared sparse"):
        nl.read_dataset(sparse, "lct")


def lct_file(tmp_path):
    path = tmp_path / "scan.mat"
    scipy.io.savemat(path, {"rect_data": np.ones((4, 3, 50)), "width": [[0.3]]})
    return path


def test_ctrl_c_while_reading_exits_130_in_one_line(tmp_path, monkeypatch, capsys):
    from nlos_cl.io import datasets

    def interrupted(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(datasets, "read_dataset", interrupted)
    out = tmp_path / "o.h5"
    assert cli(["convert", str(lct_file(tmp_path)), "--out", str(out)]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "interrupted (Ctrl-C); nothing was written to" in err[0], err
    assert not out.exists()


def test_ctrl_c_while_writing_leaves_no_part_of_the_output(tmp_path, monkeypatch, capsys):
    from nlos_cl.io import safe_write

    def interrupted(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(safe_write, "_replace", interrupted)
    src = lct_file(tmp_path)
    assert cli(["convert", str(src), "--out", str(tmp_path / "o.h5")]) == 130
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scan.mat"]


def fk_folder(tmp_path, tof, z_offset=None, width=1.0):
    folder = tmp_path / "fk"
    folder.mkdir(parents=True)
    meas = np.zeros((4, 4, 400))
    meas[..., 200] = 5.0
    scipy.io.savemat(folder / "meas_10min.mat", {"meas": meas})
    scipy.io.savemat(folder / "tof.mat", {"tofgrid": tof})
    if z_offset is not None:
        scipy.io.savemat(folder / "calibration.mat", {"z_offset": z_offset, "width": [[width]]})
    return folder


@pytest.mark.parametrize("scale, said", [(1e-3, "that looks like nanoseconds"),
                                         (1e-6, "that looks like microseconds"),
                                         (0.0, "no time of flight")])
def test_fk_tofgrid_in_another_unit_is_named(tmp_path, scale, said):
    folder = fk_folder(tmp_path, np.full((4, 4), 4000.0) * scale)
    with pytest.raises(InputError, match=r"tof\.mat: tofgrid: its median .* less than the "
                       f"0.2 m of any scan.*{said}"):
        nl.read_dataset(folder, "fk")


def test_fk_z_offset_in_millimetres_is_named(tmp_path):
    folder = fk_folder(tmp_path, np.full((4, 4), 4000.0), z_offset=np.full((4, 4), 50.0))
    with pytest.raises(InputError, match=r"calibration\.mat: z_offset: reaches 50 m off the "
                       "plane, more than the scan's 1 m side: that looks like millimetres"):
        nl.read_dataset(folder, "fk")
    folder = fk_folder(tmp_path / "b", np.full((4, 4), 4000.0),
                       z_offset=np.full((4, 4), 0.05), width=2000.0)
    with pytest.raises(InputError, match=r"calibration\.mat: width: .* got 2000: that looks "
                       "like millimetres"):
        nl.read_dataset(folder, "fk")


def test_fk_in_picoseconds_and_metres_still_reads(tmp_path):
    folder = fk_folder(tmp_path, np.full((4, 4), 4000.0), z_offset=np.full((4, 4), 0.05))
    assert nl.read_dataset(folder, "fk").data.sum() > 0


@pytest.mark.parametrize("text, said", [
    ("2.5,5.17e-8x\n3,6e-8\n4,7e-8\n", r"line 1: '5.17e-8x' is not a number, yet the row"),
    ("2.5m;5e-8s\n3;6e-8\n4;7e-8\n", r"line 1: '2.5m' is not a number"),
    ("2,5O,5.17e-8\n3,6e-8\n", r"line 1: '5O' is not a number")])
def test_a_mistyped_first_row_is_no_header(tmp_path, text, said):
    (tmp_path / "p.csv").write_text(text)
    with pytest.raises(InputError, match=said):
        read_calibration_pairs(tmp_path / "p.csv")


def test_a_header_in_words_is_still_skipped(tmp_path):
    (tmp_path / "p.csv").write_text("path (m), time (s)\n2.5,5e-8\n3,6e-8\n")
    paths, _ = read_calibration_pairs(tmp_path / "p.csv")
    assert paths.tolist() == [2.5, 3.0]


def exported(kind):
    buf = io.BytesIO()
    BOX.export(buf, file_type=kind)
    return buf.getvalue()


CUTS = {  # name: (bytes, where to cut, what the error says)
    "binary.stl": (exported("stl"), 84 + 50, "a binary STL declaring 12 triangles"),
    "ascii.stl": (exported("stl_ascii"), None, "an ASCII STL without its closing"),
    "mesh.obj": (exported("obj"), -3, "does not end with a line break"),
    "binary.ply": (exported("ply"), -30, "a PLY whose header declares 8 vertex, 12 face"),
    "mesh.off": (exported("off"), -30, "an OFF declaring 8 vertices and 12 faces"),
    "mesh.glb": (exported("glb"), -30, "a GLB declaring"),
}


@pytest.mark.parametrize("name", sorted(CUTS))
def test_a_mesh_cut_short_is_refused_not_simulated_as_its_first_faces(tmp_path, name):
    data, cut, said = CUTS[name]
    if cut is None:  # ASCII STL: after its first facet
        cut = data.index(b"endfacet") + len(b"endfacet\n")
    (tmp_path / name).write_bytes(data)
    assert len(nl.load_mesh(tmp_path / name).faces) == 12  # whole: read
    (tmp_path / name).write_bytes(data[:cut])
    with pytest.raises(InputError, match=said):
        nl.load_mesh(tmp_path / name)


def test_an_obj_face_naming_a_missing_vertex_is_refused(tmp_path):
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n")
    with pytest.raises(InputError, match=r"m\.obj"):
        nl.load_mesh(tmp_path / "m.obj")


def test_unreadable_frames_are_named_by_convert_not_skipped(tmp_path, capsys):
    folder = tmp_path / "cap"
    folder.mkdir()
    for k in range(3):
        np.savez(folder / f"volume_{k:06d}.npz", hists=np.ones((16, 128)),
                 pt_cloud=np.zeros((16, 3)))
    os.unlink(folder / "volume_000001.npz")
    os.mkfifo(folder / "volume_000001.npz")
    assert cli(["convert", str(folder), "--out", str(tmp_path / "o.h5")]) == 2
    err = capsys.readouterr().err
    assert "frame volume_000001.npz: is a FIFO" in err and not (tmp_path / "o.h5").exists()


@pytest.mark.parametrize("at, flip, said", [
    (145, 0x08, "holds complex numbers, not real ones"),  # the complex flag, no imaginary part
    (200, 0x01, "has a data element of type code 8, not a number type")])
def test_mat_v5_tags_that_crashed_scipy_are_refused(tmp_path, at, flip, said):
    """Found by test_fuzz_readers: scipy.io read these into an array of the declared dims past
    its buffer (a segmentation fault); the tags are checked first now. In a child, so the old
    code's crash fails the test instead of ending the run."""
    import subprocess
    import sys
    buf = io.BytesIO()
    scipy.io.savemat(buf, {"rect_data": np.arange(12.0).reshape(2, 2, 3), "width": [[0.3]]},
                     do_compression=False)
    raw = bytearray(buf.getvalue())
    raw[at] ^= flip
    (tmp_path / "x.mat").write_bytes(bytes(raw))
    code = ("from nlos_cl.io.datasets.matfile import load\nfrom nlos_cl.core.errors import "
            f"InputError\ntry:\n    load({str(tmp_path / 'x.mat')!r}, 'rect_data', 3)\n"
            "except InputError as exc:\n    print(exc)\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=60, check=False,
                         env=dict(os.environ, PYTHONPATH=str(Path(__file__).parents[2])))
    assert run.returncode == 0 and f"x.mat: rect_data: {said}" in run.stdout, run


def test_a_v73_chunk_that_inflates_past_its_size_is_refused(tmp_path, monkeypatch):
    """A MATLAB v7.3 variable of 2,400 bytes whose one deflate chunk inflates to 400 MB (a
    400 kB file), under a 64 MiB budget: refused in one line before HDF5 inflates it, as a
    capture's chunks are (HDF5 inflates a chunk to the end of its stream)."""
    import zlib
    monkeypatch.setenv("NLOS_CL_MEMORY_LIMIT", "64M")
    from nlos_cl.io.datasets.matfile import load
    path = tmp_path / "bomb.mat"
    with h5py.File(path, "w", userblock_size=512) as f:
        d = f.create_dataset("rect_data", (300,), dtype=np.float64, chunks=(300,),
                             compression="gzip")
        d.id.write_direct_chunk((0,), zlib.compress(bytes(400 << 20), 9), filter_mask=0)
        d.attrs["MATLAB_class"] = np.bytes_(b"double")
    with open(path, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".ljust(116)
                 + bytes(8) + b"\x00\x02IM")
    assert path.stat().st_size < 1 << 20
    with pytest.raises(InputError) as info:
        load(path, "rect_data", 1)
    text = str(info.value)
    assert "\n" not in text and "inflates to more than the 2,400 bytes" in text, text
