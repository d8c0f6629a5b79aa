"""`nlos-cl track`: the command's options and output (--json lines, --smooth, --lag, --motion)
against the library's track_sequence on the same file (tests/conftest.py's walk_file)."""
import json

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.tracking import ConstantVelocity, Interacting, read_sequence
from nlos_cl.tracking.sequences import TrackedFrame


def test_track_command_smooths_offline(walk_file, capsys):
    from nlos_cl.apps import track
    from nlos_cl.apps.cli import parser
    lines = {}
    for smooth in (False, True):  # through the parser: `nlos-cl track F --json --smooth`
        args = parser().parse_args(["track", str(walk_file), "--json", "--estimator", "paper",
                                    "--no-progress"] + (["--smooth"] if smooth else []))
        assert args.smooth is smooth
        capsys.readouterr()
        assert track.main(args) == 0
        lines[smooth] = [json.loads(x) for x in capsys.readouterr().out.splitlines()
                         if x.startswith("{")]
    causal, smoothed = lines[False], lines[True]
    assert len(smoothed) == len(causal) == 12
    assert all(e["smoothed"] for e in smoothed) and not any("smoothed" in e for e in causal)
    pos = lambda e: np.array(e["tracks"][0]["position"])  # noqa: E731
    # the last frame has no later frames: the same; earlier ones see the later frames
    np.testing.assert_allclose(pos(smoothed[-1]), pos(causal[-1]), atol=1e-5)
    assert max(np.abs(pos(s) - pos(c)).max() for s, c in zip(smoothed[2:-1], causal[2:-1])) > 1e-4


def test_track_command_prints_fixed_lag_lines(walk_file, capsys):
    """`nlos-cl track F --json --lag 3`: frame k's line after frame k + 3, with what
    Tracker.lagged(3) says of frame k then (the API run on the same file); the last 3 frames
    at the end with lags 2, 1, 0 (lag 0: the filter's own state, the causal line)."""
    from nlos_cl.apps import track
    from nlos_cl.apps.cli import parser
    out = {}
    for lag in (0, 3):
        args = parser().parse_args(["track", str(walk_file), "--json", "--no-progress", "--lag",
                                    str(lag)])
        capsys.readouterr()
        assert track.main(args) == 0
        out[lag] = [json.loads(x) for x in capsys.readouterr().out.splitlines()
                    if x.startswith("{")]
    causal, lagged = out[0], out[3]
    assert [e["frame"] for e in lagged] == list(range(12))
    assert [e["lag_frames"] for e in lagged] == [3] * 9 + [2, 1, 0]
    # the API: the same tracker settings as the command's defaults
    seq = read_sequence(walk_file)
    tracker = nl.track_sequence(seq).tracker
    expected = {}
    for fr in seq:
        tracker.update(fr.histograms, fr.t_s)
        for s in tracker.lagged(3).values():
            expected[s.frame] = seq.frame.from_internal(s.position)
    for e in lagged[3:9]:  # frames whose track is older than 3 frames
        np.testing.assert_allclose(e["tracks"][0]["position"], expected[e["frame"]], atol=2e-5)
    np.testing.assert_allclose(lagged[-1]["tracks"][0]["position"],
                               causal[-1]["tracks"][0]["position"], atol=1e-5)
    assert max(abs(np.array(a["tracks"][0]["position"]) - b["tracks"][0]["position"]).max()
               for a, b in zip(lagged[3:9], causal[3:9])) > 1e-4
    with pytest.raises(nl.InputError, match="--lag"):
        track.main(parser().parse_args(["track", str(walk_file), "--lag", "2", "--smooth"]))


def test_track_command_motion_options():
    from nlos_cl.apps.cli import parser
    from nlos_cl.apps.track import motion_model
    parse = lambda *a: parser("track").parse_args(["track", "walk.h5", *a])  # noqa: E731
    assert motion_model(parse()) == Interacting(accel_sigmas=(0.05, 0.5))
    assert motion_model(parse("--motion", "cv", "--accel", "0.3")) == ConstantVelocity(0.3)
    assert motion_model(parse("--steady-accel", "0.02", "--accel", "1")) == Interacting(
        accel_sigmas=(0.02, 1.0))
    with pytest.raises(nl.InputError, match="--steady-accel"):
        motion_model(parse("--steady-accel", "1"))


def test_a_run_yields_each_frame_and_agrees_with_the_command(walk_file, capsys):
    """The library's frames are the command's JSON lines: same tracks, same positions (the
    command prints them in the file's frame; here they are converted back)."""
    from nlos_cl.apps import track
    from nlos_cl.apps.cli import parser
    run = nl.track_sequence(walk_file, estimator="paper")
    steps = list(run)
    assert len(run) == len(steps) == 12
    assert all(isinstance(s, TrackedFrame) and s.frame.histograms is None for s in steps)
    assert [s.frame.index for s in steps] == list(range(12))
    args = parser().parse_args(["track", str(walk_file), "--json", "--estimator", "paper",
                                "--no-progress"])
    capsys.readouterr()
    assert track.main(args) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines() if x.startswith("{")]
    assert len(lines) == 12
    cframe = run.sequence.frame
    for step, line in zip(steps, lines):
        assert [t.id for t in step.tracks] == [t["id"] for t in line["tracks"]]
        for t, printed in zip(step.tracks, line["tracks"]):
            np.testing.assert_allclose(cframe.from_internal(t.position), printed["position"],
                                       atol=5.1e-6)  # the JSON's 5 decimals
    # the copies keep each frame's state: the last track moved on after the first frames
    first = [s for s in steps if s.tracks][0].tracks[0]
    last = steps[-1].tracks[0]
    assert first.id == last.id and np.linalg.norm(first.position - last.position) > 0.1


def test_a_sequence_without_target_signal_exits_3_and_says_so_per_frame(walk_file, tmp_path,
                                                                         capsys):
    """The walk's layout and record with noise alone: every line "detected": false, no
    track, exit 3 (as `nlos-cl locate`), where the command used to exit 0."""
    from nlos_cl.apps.cli import main
    seq = read_sequence(walk_file)
    rng = np.random.default_rng(0)
    noise = [(f.t_s, nl.HistogramSet(rng.normal(0.0, 1e-9, f.histograms.data.shape),
                                     f.histograms.time_axis, f.histograms.detector_spots,
                                     f.histograms.laser_spot, f.histograms.calibration))
             for f in seq]
    path = nl.write_sequence(tmp_path / "noise.h5", noise)
    capsys.readouterr()
    assert main(["track", str(path), "--json", "--no-progress"]) == 3
    out = capsys.readouterr()
    lines = [json.loads(x) for x in out.out.splitlines() if x.startswith("{")]
    assert len(lines) == len(seq) and not any(e["detected"] for e in lines)
    assert all(e["tracks"] == [] for e in lines)
    assert "no target signal in any of the 12 frames" in out.err


def test_a_frames_warnings_name_the_frame_they_come_from(walk_file, monkeypatch, capsys):
    """`nlos-cl track`: a warning raised while a frame is tracked (the estimator's "the depth of
    target 1 was not found", NumPy's divide by zero) names that frame's number and time; the
    later frames that gave the same text are listed once after the last frame. Warnings are
    raised here by the tracker itself on frames 3, 4, 5 and 9 (and 7: another text)."""
    import warnings
    from nlos_cl.apps.cli import main
    from nlos_cl.tracking.tracker import Tracker
    update, frames = Tracker.update, iter(range(12))

    def warning_update(self, hist, t_s):
        k = next(frames)
        if k in (3, 4, 5, 9):
            warnings.warn("the depth of target 1 was not found: a test", UserWarning)
        if k == 7:
            warnings.warn("divide by zero encountered in divide", RuntimeWarning)
        return update(self, hist, t_s)
    monkeypatch.setattr(Tracker, "update", warning_update)
    capsys.readouterr()
    assert main(["track", str(walk_file), "--estimator", "paper", "--no-progress"]) == 0
    said = [x for x in capsys.readouterr().err.splitlines() if "a test" in x or "divide" in x]
    assert said == [
        "nlos-cl: warning: frame 3 (t 0.300 s): the depth of target 1 was not found: a test",
        "nlos-cl: warning: frame 7 (t 0.700 s): divide by zero encountered in divide",
        "nlos-cl: warning: the depth of target 1 was not found: a test (again: frames 4-5, 9, "
        "t 0.400 .. 0.900 s)"]
