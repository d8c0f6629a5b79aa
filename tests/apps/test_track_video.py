"""`nlos-cl track SEQ --video out.gif`: each frame's joint map (the Locator's) under the tracks,
written frame by frame into an atomic write."""
import contextlib
import io
import json
import os
import shutil
import subprocess

import numpy as np
import pytest
from PIL import Image

import nlos_cl as nl
from nlos_cl.io.safe_write import MANIFEST
from nlos_cl.apps import track, track_video
from nlos_cl.ops.backend import NumpyBackend
from nlos_cl.apps.cli import parser
from nlos_cl.tracking import read_sequence, write_sequence

N_FRAMES = 8
# a small region (y-tal axes: -x, z, y): 101 x 91 cells around the walk
REGION = ["--region", "-4.5", "-2", "0", "0", "1", "3.25", "--step", "0.025"]


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    from nlos_cl.tracking import MovingTarget, Trajectory, simulate_sequence
    setup = nl.paper_setup()
    path = Trajectory([0, 0.8], [[2.6, 1.6, 0], [3.4, 2.4, 0]])
    target = MovingTarget(nl.Target(nl.rectangle(centre=path.at(0), cell_m=0.03)), path)
    frames = simulate_sequence(setup, target, n_frames=N_FRAMES, fps=10, noise=nl.AWGN(10),
                               seed=0, facet_size_m=0.03,
                               time_axis=nl.default_time_axis(setup, 1e-11))
    return write_sequence(tmp_path_factory.mktemp("walk") / "walk.h5", frames)


def _track(walk, *extra):
    args = parser().parse_args(["track", str(walk), "--estimator", "paper", "--no-progress",
                                *REGION, *extra])
    return track.main(args)


@pytest.fixture(scope="module")
def recorded(walk, tmp_path_factory):
    """One `--json --video` run, with every map handed to the drawing recorded."""
    records, draw = [], track_video.Video.draw

    def spy(self, frame, tracks, measurements, scores):
        records.append((frame.index, frame.truths, self.grid, self.log_mode,
                        None if scores is None else scores.copy()))
        return draw(self, frame, tracks, measurements, scores)
    gif = tmp_path_factory.mktemp("video") / "tracks.gif"
    out = io.StringIO()  # (a module-scoped fixture cannot use capsys)
    with pytest.MonkeyPatch.context() as mp, contextlib.redirect_stdout(out):
        mp.setattr(track_video.Video, "draw", spy)
        assert _track(walk, "--json", "--video", str(gif)) == 0
    return gif, records, [json.loads(x) for x in out.getvalue().splitlines()
                          if x.startswith("{")]


@pytest.mark.filterwarnings("ignore:height .z. is unobservable")
def test_drawn_map_is_the_locators_joint_map(walk, recorded):
    _, records, lines = recorded
    assert [r[0] for r in records] == list(range(N_FRAMES))
    assert len(lines) == N_FRAMES  # --json still streams a line per frame
    from nlos_cl.tracking.sequences import sampled_frames
    from nlos_cl.tracking.static import static_background
    seq, ref = read_sequence(walk), NumpyBackend()
    learned = static_background(sampled_frames(seq))  # what `track` subtracts by default
    for index, truths, grid, log_mode, scores in records[2::3]:
        assert scores.shape == (grid.shape[1], grid.shape[0]) and not log_mode  # (ny, nx)
        h = seq[index].histograms  # recomputed independently: float64 NumPy twins
        h = h if learned is None else h.with_data(h.data - learned.data)
        expected = nl.locate(nl.gauss_filter(h, 0.65e-9, backend=ref), grid, return_map=True,
                             backend=ref).score_map
        assert expected.shape == (1,) + scores.shape
        # the device's float32 filter and kernel (~1e-5 here): within 1e-4 of the peak
        np.testing.assert_allclose(scores, expected[0], rtol=0, atol=1e-4 * expected.max())
        iy, ix = np.unravel_index(np.argmax(scores), scores.shape)
        x, y, _ = grid.axes()
        assert np.hypot(x[ix] - truths[0, 0], y[iy] - truths[0, 1]) < 0.15


def test_display_scale_is_the_same_for_products_and_log_sums():
    rng = np.random.default_rng(0)
    factors = rng.uniform(0.05, 1.0, (3, 20, 30))  # three detectors' normalised likelihoods
    product, log_sum = factors.prod(axis=0), np.log(factors).sum(axis=0)
    shown = track_video._display(product, False, 3)
    np.testing.assert_allclose(shown, track_video._display(log_sum, True, 3), rtol=1e-12)
    np.testing.assert_allclose(shown, (product / product.max()) ** (1 / 3))
    assert shown.max() == pytest.approx(1.0) and shown.min() > 0.05
    assert not track_video._display(np.zeros((4, 5)), False, 3).any()  # no signal: a dark map
    assert track_video._display(None, False, 3) is None


def _frames(gif):
    with Image.open(gif) as im:
        out = []
        for k in range(im.n_frames):
            im.seek(k)
            out.append(np.asarray(im.convert("RGB"), dtype=float))
        return out


def test_gif_has_a_frame_per_tracked_frame_and_shows_the_map(walk, recorded, tmp_path,
                                                             monkeypatch, capsys):
    frames = _frames(recorded[0])
    assert len(frames) == N_FRAMES and frames[0].shape == (500, 600, 3)
    h, w, _ = frames[0].shape
    inner = lambda f: f[int(0.3 * h):int(0.7 * h), int(0.2 * w):int(0.6 * w)]  # noqa: E731
    # without the map (blank under the tracks), with --smooth: the video stays causal
    monkeypatch.setattr(track_video, "joint_map", lambda tracker: None)
    blank = tmp_path / "blank.gif"
    assert _track(walk, "--json", "--smooth", "--max-frames", "3", "--video", str(blank)) == 0
    smoothed = [json.loads(x) for x in capsys.readouterr().out.splitlines() if x[:1] == "{"]
    assert len(smoothed) == 3 and all(e["smoothed"] for e in smoothed)
    blanks = _frames(blank)
    assert len(blanks) == 3
    for k in (1, 2):  # the same tracks drawn: the frames differ by the map alone
        assert inner(frames[k]).std() > inner(blanks[k]).std() + 20
        changed = np.abs(frames[k] - blanks[k]).sum(axis=2) > 60
        assert changed.mean() > 0.03 and not changed[:, :int(0.04 * w)].any()  # in the axes
    assert np.abs(inner(frames[1]) - inner(frames[-1])).mean() > 1  # the map moves


def test_bad_video_paths_are_refused_before_tracking(walk, tmp_path, monkeypatch):
    for path, message in ((tmp_path / "v.avi", "neither .gif nor .mp4"),
                          (tmp_path / "no" / "v.gif", "does not exist"),
                          (walk, "neither")):
        with pytest.raises(nl.InputError, match=f"--video.*{message}"):
            _track(walk, "--video", str(path))
    old = tmp_path / "old.gif"
    old.write_bytes(b"old")
    with pytest.raises(nl.InputError, match="--video.*exists.*--force"):
        _track(walk, "--video", str(old))
    assert old.read_bytes() == b"old"
    from matplotlib import animation
    monkeypatch.setattr(animation.writers, "is_available", lambda name: False)
    with pytest.raises(nl.InputError, match="--video.*ffmpeg"):
        _track(walk, "--video", str(tmp_path / "v.mp4"))
    assert sorted(os.listdir(tmp_path)) == ["old.gif"]


@pytest.mark.parametrize("interrupt", [KeyboardInterrupt, RuntimeError])
def test_interrupted_video_leaves_no_file_and_no_temporary(walk, tmp_path, monkeypatch,
                                                           interrupt):
    grab, calls = track_video._GifWriter.grab_frame, []

    def failing(self):
        calls.append(1)
        if len(calls) == 2:
            raise interrupt("frame 2")
        return grab(self)
    monkeypatch.setattr(track_video._GifWriter, "grab_frame", failing)
    new, old = tmp_path / "new.gif", tmp_path / "old.gif"
    old.write_bytes(b"old")
    for path, force in ((new, []), (old, ["--force"])):
        calls.clear()
        with pytest.raises(interrupt):
            _track(walk, "--max-frames", "4", "--video", str(path), *force)
    assert sorted(os.listdir(tmp_path)) == ["old.gif"] and old.read_bytes() == b"old"
    monkeypatch.setattr(track_video._GifWriter, "grab_frame", grab)  # a complete write replaces it
    assert _track(walk, "--max-frames", "2", "--video", str(old), "--force") == 0
    # a GIF carries no mark of ours: the folder's manifest (io/safe_write.py) says we wrote it
    assert sorted(os.listdir(tmp_path)) == [MANIFEST, "old.gif"] and Image.open(old).n_frames == 2


@pytest.mark.skipif(shutil.which("ffmpeg") is None, reason="no ffmpeg on the PATH")
def test_mp4_through_ffmpeg_appears_whole_or_not_at_all(walk, tmp_path, monkeypatch):
    from matplotlib import animation
    good, bad = tmp_path / "tracks.mp4", tmp_path / "broken.mp4"
    assert _track(walk, "--max-frames", "3", "--video", str(good)) == 0
    probe = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0",
                            "-show_entries", "stream=nb_read_frames", "-of", "csv=p=0",
                            str(good)], capture_output=True, text=True, check=True)
    assert probe.stdout.strip() == "3"
    grab = animation.FFMpegWriter.grab_frame

    def failing(self, **kw):
        if getattr(self, "_grabbed", 0) == 1:
            raise KeyboardInterrupt("frame 2")
        self._grabbed = 1
        return grab(self, **kw)
    monkeypatch.setattr(animation.FFMpegWriter, "grab_frame", failing)
    with pytest.raises(KeyboardInterrupt):
        _track(walk, "--max-frames", "3", "--video", str(bad))
    assert sorted(os.listdir(tmp_path)) == ["tracks.mp4"]  # no broken.mp4, no .tmp(.mp4)


def test_a_file_that_appears_during_the_run_is_kept(walk, tmp_path, monkeypatch):
    """A file someone else writes at the --video path while we track is not replaced by ours:
    the check before tracking saw no file, and the atomic write's concurrent-writer check at
    the end sees theirs (io/safe_write.py), whatever --force says."""
    grab, path = track_video._GifWriter.grab_frame, tmp_path / "tracks.gif"

    def appearing(self):
        if not path.exists():
            path.write_bytes(b"theirs")
        return grab(self)
    monkeypatch.setattr(track_video._GifWriter, "grab_frame", appearing)
    with pytest.raises(nl.InputError, match="--video"):
        _track(walk, "--max-frames", "2", "--video", str(path))
    assert path.read_bytes() == b"theirs"
