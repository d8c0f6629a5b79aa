"""A full disk ends in a one-line error and leaves nothing behind: captures are built in
memory and written as bytes; a sequence checks the free space before HDF5 writes its frames
(HDF5 meeting a full disk segfaulted in both)."""
import errno
import shutil
from collections import namedtuple

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.io.ytal import capture, sequence


@pytest.fixture(scope="module")
def frame():
    return nl.simulate(nl.paper_scene()).histograms()


def test_a_capture_on_a_full_disk_is_one_error_and_no_file(tmp_path, monkeypatch, frame):
    def full(path, mode="r", *args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))
    monkeypatch.setattr(capture, "open", full, raising=False)
    with pytest.raises(nl.InputError, match="could not be written.*No space left"):
        nl.write_capture(tmp_path / "c.h5", frame)
    assert list(tmp_path.iterdir()) == []


def test_a_sequence_checks_the_free_space_before_writing(tmp_path, monkeypatch, frame):
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda p: usage(1 << 30, 1 << 30, 200_000))
    frames = [(k * 0.1, frame) for k in range(3)]
    with pytest.raises(nl.InputError, match="MiB free, and the next frames need"):
        sequence.write_sequence(tmp_path / "s.h5", frames, fps=10)
    assert list(tmp_path.iterdir()) == []
    monkeypatch.undo()
    out = sequence.write_sequence(tmp_path / "s.h5", frames, fps=10)
    from nlos_cl.tracking import read_sequence
    assert len(read_sequence(out)) == 3 and np.isfinite(frame.data).all()
