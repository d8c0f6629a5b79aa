"""Sequence files: y-tal fields with a leading frame axis, written atomically, read lazily."""
import os
import tracemalloc

import h5py
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.tracking import read_sequence, write_sequence

C = nl.SPEED_OF_LIGHT


def _hist(k, n_bins=512, truth=True):
    rng = np.random.default_rng(k)
    axis = nl.TimeAxis(40 / C, 10e-12, n_bins)
    spots = [[-0.5, 0, 0], [-1, 0, 0], [-1.5, 0, 0]]
    cal = nl.PathCalibration(C, [-40.0])
    pos = [3 + 0.1 * k, 2, 0]
    return nl.HistogramSet(rng.random((3, n_bins)) * 1e-13, axis, spots, [0, 0, 0], cal,
                           truth=pos if truth else None,
                           truths=[pos, [2, 4, 0]] if truth else None)


def test_round_trip_with_timestamps_and_truths(tmp_path):
    frames = [(0.1 * k, _hist(k)) for k in range(7)]
    path = write_sequence(tmp_path / "seq.h5", frames, metadata={"scene": "test"})
    with h5py.File(path) as f:  # y-tal's fields, H with a leading frame axis
        assert f["H"].shape == (7, 512, 3) and f["H"].chunks == (1, 512, 3)
        assert f["frame_truths"].shape == (7, 2, 3)
        assert {"H_format", "sensor_grid_xyz", "laser_grid_xyz", "delta_t", "t_start"} <= set(f)
    seq = read_sequence(path)
    assert len(seq) == 7 and seq.metadata == {"scene": "test"}
    np.testing.assert_allclose(seq.t_s, [0.1 * k for k in range(7)])
    for (t, h), got in zip(frames, seq):
        assert got.t_s == t
        np.testing.assert_allclose(got.histograms.data, h.data, rtol=1e-6)
        assert got.histograms.time_axis == h.time_axis
        np.testing.assert_allclose(got.truths, h.truths)
        np.testing.assert_allclose(got.histograms.truth, h.truth)
    np.testing.assert_allclose(seq[-1].histograms.data, frames[-1][1].data, rtol=1e-6)


def test_one_frame_is_a_plain_capture(tmp_path):
    path = write_sequence(tmp_path / "one.h5", [(2.5, _hist(1))])
    (h,) = nl.read_capture(path)  # a plain y-tal capture
    np.testing.assert_allclose(h.data, _hist(1).data, rtol=1e-6)
    with h5py.File(path) as f:
        assert f["H"].shape == (512, 3) and "frame_t_s" not in f
    (frame,) = list(read_sequence(path))
    assert frame.t_s == 2.5
    np.testing.assert_allclose(frame.truths, _hist(1).truths)


def test_plain_capture_reads_as_one_frame(tmp_path):
    path = nl.write_capture(tmp_path / "cap.h5", _hist(2))
    seq = read_sequence(path)
    assert len(seq) == 1 and seq[0].t_s == 0.0
    np.testing.assert_allclose(seq[0].truths, [_hist(2).truth])


def test_signals_and_fps_timing(tmp_path):
    sig = [nl.upload(_hist(k), "reference") for k in range(3)]
    seq = read_sequence(write_sequence(tmp_path / "s.h5", sig, fps=4.0))
    np.testing.assert_allclose(seq.t_s, [0, 0.25, 0.5])
    assert seq.fps == 4.0


def test_lazy_reading_holds_one_frame(tmp_path):
    n_bins, n = 4096, 60
    path = write_sequence(tmp_path / "long.h5", ((0.1 * k, _hist(k % 3, n_bins, False))
                                                  for k in range(n)))
    seq = read_sequence(path)
    tracemalloc.start()
    for frame in seq:
        assert frame.histograms.data.shape == (3, n_bins)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    one_frame = 3 * n_bins * 8
    assert peak < 8 * one_frame, peak  # all 60 frames would be 60 x


def test_interrupted_write_keeps_the_old_file(tmp_path):
    path = write_sequence(tmp_path / "seq.h5", [(0.0, _hist(0)), (0.1, _hist(1))])
    before = path.read_bytes()

    def broken():
        yield 0.0, _hist(0)
        yield 0.1, _hist(1)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_sequence(path, broken())
    assert path.read_bytes() == before
    # no temporary file left (the manifest holds the first write's SHA-256: issue 59)
    assert sorted(os.listdir(tmp_path)) == ["files-written-by-nlos_cl.json", "seq.h5"]


def test_bad_frames_are_refused(tmp_path):
    other = _hist(1, n_bins=256)
    with pytest.raises(nl.InputError, match=r"frames\[1\]"):
        write_sequence(tmp_path / "x.h5", [(0.0, _hist(0)), (0.1, other)])
    with pytest.raises(nl.InputError, match="frames.t_s"):
        write_sequence(tmp_path / "x.h5", [(0.1, _hist(0)), (0.1, _hist(1))])
    with pytest.raises(nl.InputError, match="frames"):
        write_sequence(tmp_path / "x.h5", [])
    with pytest.raises(nl.InputError, match="fps"):
        write_sequence(tmp_path / "x.h5", [_hist(0), _hist(1)])
    assert not (tmp_path / "x.h5").exists()
    (tmp_path / "notes.txt").write_text("keep me")
    with pytest.raises(nl.InputError, match="not an HDF5 capture"):
        write_sequence(tmp_path / "notes.txt", [(0.0, _hist(0)), (0.1, _hist(1))])


def test_truncated_sequence_is_refused(tmp_path):
    path = write_sequence(tmp_path / "seq.h5", [(0.1 * k, _hist(k)) for k in range(4)])
    data = path.read_bytes()
    cut = tmp_path / "cut.h5"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(nl.InputError, match="incomplete or corrupted"):
        list(read_sequence(cut))
