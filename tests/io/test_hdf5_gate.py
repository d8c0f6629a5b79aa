"""Issue 59 item 1 for HDF5 (nlos_cl.io.hdf5_gate): captures and sequences pass the one input
gate. What HDF5 itself does not bound is refused in one line before it is read: a compressed
chunk that inflates past its declared size, chunks declared larger than their dataset, two
compressions in one pipeline, links and external storage anywhere in the tree, a variable-length
field of many elements, a sequence's per-frame truths of 10^7 targets; valid files still read."""
import zlib

import h5py
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.core.errors import InputError
from nlos_cl.tracking import read_sequence, write_sequence

C = nl.SPEED_OF_LIGHT
SPOTS = np.array([[-0.5, 0, 0], [-1.0, 0, 0], [-1.5, 0, 0]])


def hist(n_bins=200, scale=1.0):
    data = scale * (1.0 + np.arange(3 * n_bins).reshape(3, n_bins) % 7)
    return nl.HistogramSet(data, nl.TimeAxis(2 * 20 / C, 10e-12, n_bins), SPOTS, [0, 0, 0],
                           nl.PathCalibration(C, [-40.0]))


@pytest.fixture
def budget(monkeypatch):
    monkeypatch.setenv("NLOS_CL_MEMORY_LIMIT", "64M")


def one_line(exc, path, *words):
    text = str(exc)
    assert "\n" not in text and path.name in text and "Fix:" in text, text
    for word in words:
        assert word in text, text
    return text


def replace_h(path, make):
    """H recreated by make(f) (the other fields kept)."""
    with h5py.File(path, "a") as f:
        del f["H"]
        make(f)


def test_a_chunk_that_inflates_past_its_declared_size_is_refused(tmp_path, budget):
    """HDF5 inflates a deflate chunk to its stream's end whatever the chunk declares: this
    ~400 kB file's 2.4 kB chunk holds 400 MB of zeros (read before: 440 MB resident, then the
    first 2.4 kB kept, no word). Refused before HDF5 reads it."""
    path = nl.write_capture(tmp_path / "bomb.h5", hist())

    def bomb(f):
        d = f.create_dataset("H", (200, 3), dtype=np.float32, chunks=(200, 3),
                             compression="gzip")
        d.id.write_direct_chunk((0, 0), zlib.compress(bytes(400 << 20), 9), filter_mask=0)
    replace_h(path, bomb)
    assert path.stat().st_size < 1 << 20
    with pytest.raises(InputError) as info:
        nl.read_capture(path)
    one_line(info.value, path, "H: chunk at (0, 0)", "inflates to more than the 2,400 bytes")


def test_compressed_captures_and_sequences_still_read(tmp_path, budget):
    """Valid gzip captures (chunks that could expand past the budget are inflated here first)
    and sequences read as written."""
    big = hist(n_bins=200_000)  # a 2.4 MB chunk: 1032 x its stored size passes 64 MiB
    path = nl.write_capture(tmp_path / "c.h5", big, compression=9)
    np.testing.assert_allclose(nl.read_capture(path)[0].data, big.data, rtol=1e-6)
    seq = write_sequence(tmp_path / "s.h5", [(0.1 * k, hist(scale=k + 1.0)) for k in range(3)],
                         compression=4)
    frames = list(read_sequence(seq))
    assert [fr.histograms.data.max() for fr in frames] == [7.0, 14.0, 21.0]


def test_chunks_larger_than_their_dataset_are_refused(tmp_path, budget):
    """An extendible H of 200 x 3 values declaring 80 MB chunks: each read would allocate the
    whole chunk."""
    path = nl.write_capture(tmp_path / "chunky.h5", hist())

    def chunky(f):
        d = f.create_dataset("H", (200, 3), maxshape=(None, 3), dtype=np.float32,
                             chunks=(20_000_000, 1))
        d[...] = 1.0
    replace_h(path, chunky)
    with pytest.raises(InputError) as info:
        nl.read_capture(path)
    one_line(info.value, path, "H: declares chunks of 76.29 MiB", "MiB this reader may hold")


def test_two_compressions_in_one_pipeline_are_refused(tmp_path):
    path = nl.write_capture(tmp_path / "twice.h5", hist())

    def twice(f):
        dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
        dcpl.set_chunk((200, 3))
        dcpl.set_deflate(4)
        dcpl.set_deflate(4)
        space = h5py.h5s.create_simple((200, 3))
        h5py.h5d.create(f.id, b"H", h5py.h5t.NATIVE_FLOAT, space, dcpl=dcpl)
        f["H"][...] = 1.0
    replace_h(path, twice)
    with pytest.raises(InputError) as info:
        nl.read_capture(path)
    one_line(info.value, path, "H: is compressed twice over")


@pytest.mark.parametrize("where", ["top", "group"])
def test_links_anywhere_in_the_tree_are_refused(tmp_path, where):
    """An external link is refused wherever it sits, before any field is looked up."""
    secret = tmp_path / "secret.h5"
    with h5py.File(secret, "w") as f:
        f["data"] = np.arange(3.0)
    path = nl.write_capture(tmp_path / "linked.h5", hist())
    with h5py.File(path, "a") as f:
        group = f if where == "top" else f.create_group("extra")
        group["peek"] = h5py.ExternalLink(str(secret), "/data")
    with pytest.raises(InputError) as info:
        nl.read_capture(path)
    one_line(info.value, path, "peek: is an external link")


def test_a_variable_length_field_is_bounded_by_the_file(tmp_path, budget):
    """scene_info as 5,000 variable-length strings: each may point at any heap object of the
    file (aliases are not stored twice), so it counts as 5,000 x the file's free bytes."""
    path = nl.write_capture(tmp_path / "vlen.h5", hist())
    with h5py.File(path, "a") as f:
        del f["scene_info"]
        f.create_dataset("scene_info", data=np.array(["x" * 1000] * 5000, dtype=object),
                         dtype=h5py.string_dtype())
    with pytest.raises(InputError) as info:
        nl.read_capture(path)
    one_line(info.value, path, "scene_info: declares", "scene_info (5000,) object")


def test_unused_fields_are_neither_counted_nor_read(tmp_path, budget):
    """A field nlos_cl does not read (a 3 GiB dataset, never written) costs nothing."""
    path = nl.write_capture(tmp_path / "unused.h5", hist())
    with h5py.File(path, "a") as f:
        f.create_dataset("notes", shape=(1 << 30,), dtype=np.float32, chunks=(1 << 16,))
    assert nl.read_capture(path)[0].data.shape == (3, 200)


def test_a_sequence_whose_frame_truths_declare_ten_million_targets(tmp_path, budget):
    """Each frame reads its row of frame_truths: (F, 10^7, 3) is 240 MB a frame."""
    path = write_sequence(tmp_path / "seq.h5", [(0.1 * k, hist()) for k in range(3)])
    with h5py.File(path, "a") as f:
        f.create_dataset("frame_truths", shape=(3, 10_000_000, 3), dtype=np.float64,
                         chunks=(1, 10_000, 3))
    with pytest.raises(InputError) as info:
        read_sequence(path)
    one_line(info.value, path, "frame_truths: declares", "1 row(s) at a time")


def test_a_sequence_declaring_a_billion_frames(tmp_path, budget):
    path = write_sequence(tmp_path / "seq.h5", [(0.1 * k, hist()) for k in range(3)])
    with h5py.File(path, "a") as f:
        f["H"].resize(10 ** 9, axis=0)
        f["frame_t_s"].resize(10 ** 9, axis=0)
    with pytest.raises(InputError) as info:
        read_sequence(path)
    one_line(info.value, path, "1,000,000,000 frames declared")
