"""Range tracks (nlos_cl.tracking.ranges; `nlos-cl track` on a sequence of one confocal spot,
Keyhole's layout): the filter against the truth on noisy synthetic ranges, the measured sigma,
the CLI's JSON and refusals, and the reading rules that make such a file a confocal set."""
import json
import math

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.apps.cli import main as cli
from nlos_cl.localization.ranges import is_single_confocal
from nlos_cl.tracking import ConstantVelocity, read_sequence, write_sequence
from nlos_cl.tracking.ranges import range_sigma, track_ranges

C = nl.SPEED_OF_LIGHT


def _stage(n=120, seed=0, noise=0.01):
    """A stage that sweeps 0.72 .. 0.99 m at 1 Hz (Keyhole's K), measured with `noise`."""
    t = np.arange(n, dtype=float)
    truth = 0.85 + 0.13 * np.sin(2 * np.pi * t / 90.0)
    return t, truth, truth + noise * np.random.default_rng(seed).standard_normal(n)


def test_the_filter_follows_the_range_closer_than_the_frames():
    """0.01 m white noise on a slow sweep (at most 0.6 mm/s^2): with a motion model of the
    stage's scale (--motion cv --accel 0.002) the causal filter's RMS is below 0.8 x the
    frames' (from frame 10) and the smoother's below the filter's. The default IMM is scaled
    for walkers at video rates (0.05 / 0.5 m/s^2): at 1 Hz it lets a 0.25 m step through in
    one frame, so it follows the frames (within 5 % of their RMS), which it must not make
    worse."""
    t, truth, z = _stage()
    sigma = range_sigma(z, 1e-4)
    assert 0.007 < sigma < 0.014  # the noise's 0.01, from second differences
    rms = lambda x: math.sqrt(np.mean((x[10:] - truth[10:]) ** 2))  # noqa: E731

    def ranges(motion, smooth=False):
        return np.array([p.range_m for p in track_ranges(z, t, motion=motion, sigma_m=sigma,
                                                         smooth=smooth)])
    stage = ConstantVelocity(accel_sigma=0.002)
    assert rms(ranges(stage)) < 0.8 * rms(z), (rms(ranges(stage)), rms(z))
    assert rms(ranges(stage, smooth=True)) < rms(ranges(stage))
    assert rms(ranges(None)) < 1.05 * rms(z)


def test_points_carry_the_frames_measurements_and_a_rate():
    t, truth, z = _stage(noise=0.0)
    points = track_ranges(z, t, sigma_m=0.001)
    assert [p.frame for p in points] == list(range(len(z)))
    assert np.allclose([p.measured_m for p in points], z)
    rate = np.gradient(truth, t)
    assert abs(points[50].speed_m_s - rate[50]) < 0.002  # m/s: the sweep's own rate
    assert all(p.range_sd_m > 0 for p in points)


def test_range_sigma_keeps_its_floor_and_bad_inputs_are_named():
    assert range_sigma([0.5, 0.5, 0.5, 0.5], 0.002) == 0.002
    with pytest.raises(nl.InputError, match="^times_s: "):
        track_ranges([1.0, 1.1], [0.0, 0.0], sigma_m=0.01)
    with pytest.raises(nl.InputError, match="^measured: "):
        track_ranges([1.0, 1.1], [0.0], sigma_m=0.01)
    with pytest.raises(nl.InputError, match="^sigma_m: "):
        track_ranges([1.0, 1.1], [0.0, 1.0], sigma_m=0.0)


def _confocal_sequence(tmp_path, n=12):
    """A one-spot confocal sequence whose range sweeps (a Gaussian return at 2 r)."""
    axis = nl.TimeAxis(0.0, 16e-12, 768)
    centres = axis.centres() if hasattr(axis, "centres") else \
        axis.t0_s + axis.dt_s * (np.arange(axis.n_bins) + 0.5)
    t, truth, _ = _stage(n, noise=0.0)
    frames = []
    for k in range(n):
        y = np.exp(-0.5 * ((centres * C - 2 * truth[k]) / 0.02) ** 2)[None]
        h = nl.HistogramSet(y, axis, [(0.0, 0.0, 0.0)], [(0.0, 0.0, 0.0)],
                            nl.PathCalibration(C, [0.0]))
        frames.append((float(t[k]), h))
    return write_sequence(tmp_path / "spot.h5", frames, fps=1.0), truth


def test_track_command_follows_one_confocal_spot(tmp_path, capsys):
    path, truth = _confocal_sequence(tmp_path)
    assert is_single_confocal(read_sequence(path)[0].histograms)
    assert cli(["track", str(path), "--json", "--no-progress"]) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert [e["frame"] for e in lines] == list(range(len(truth)))
    got = np.array([e["range_m"] for e in lines])
    assert np.max(np.abs(got - truth)) < 0.003  # a 16 ps bin is 2.4 mm of range
    assert cli(["track", str(path), "--json", "--smooth", "--no-progress"]) == 0
    assert all(json.loads(x)["smoothed"] for x in capsys.readouterr().out.splitlines())


@pytest.mark.parametrize("extra, flag", [(["--targets", "2"], "--targets"),
                                         (["--estimator", "model"], "--estimator"),
                                         (["--video", "v.gif"], "--video"),
                                         (["--json", "--lag", "2"], "--lag")])
def test_track_command_refuses_what_places_targets(tmp_path, capsys, extra, flag):
    path, _ = _confocal_sequence(tmp_path, n=5)
    assert cli(["track", str(path), "--no-progress", *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"nlos-cl: {flag}: does not apply"), err


def test_locate_on_a_sequence_file_says_so(tmp_path, capsys):
    path, _ = _confocal_sequence(tmp_path, n=3)
    with pytest.raises(nl.InputError, match="is a sequence of frames .* Fix: track it"):
        nl.read_capture(path)


def test_one_laser_on_one_sensor_is_confocal_one_elsewhere_is_not(tmp_path):
    """y-tal pairs a one-point laser grid with a one-point sensor grid of the same format; here
    that is the confocal spot where the two coincide, and one laser with one detector
    elsewhere stays the one-laser layout."""
    axis = nl.TimeAxis(0.0, 16e-12, 64)
    y = np.ones((1, 64))
    same = nl.HistogramSet(y, axis, [(0.3, 0.0, 0.0)], [(0.3, 0.0, 0.0)],
                           nl.PathCalibration(C, [0.0]))
    apart = nl.HistogramSet(y, axis, [(0.3, 0.0, 0.0)], (0.0, 0.0, 0.0),
                            nl.PathCalibration(C, [0.0]))
    for h, paired in ((same, True), (apart, False)):
        path = tmp_path / f"{paired}.h5"
        nl.write_capture(path, h)
        [back] = nl.read_capture(path)
        assert back.paired is paired
        assert is_single_confocal(back) is paired


def _noisy_spot(tmp_path, returns, seed=0):
    """A one-spot confocal sequence of white noise, with a return (at 2 x 1.5 m of path) only
    in the frames where `returns` is True."""
    axis = nl.TimeAxis(0.0, 16e-12, 768)
    centres = axis.t0_s + axis.dt_s * (np.arange(axis.n_bins) + 0.5)
    rng = np.random.default_rng(seed)
    frames = []
    for k, seen in enumerate(returns):
        y = rng.normal(0.0, 0.1, (1, axis.n_bins))
        if seen:
            y += np.exp(-0.5 * ((centres * C - 3.0) / 0.02) ** 2)
        frames.append((float(k), nl.HistogramSet(y, axis, [(0.0, 0.0, 0.0)], [(0.0, 0.0, 0.0)],
                                                 nl.PathCalibration(C, [0.0]))))
    return write_sequence(tmp_path / "noise.h5", frames, fps=1.0)


def test_a_spot_without_a_return_is_no_target_and_a_missing_frame_is_coasted(tmp_path, capsys):
    """Noise alone: no range (null), "detected": false on every line, exit 3 as `locate`'s
    (the strongest noise bin was reported as a range before). One frame without its return in
    a run of returns: measured null there, the filter's range carried over it."""
    path = _noisy_spot(tmp_path, [False] * 6)
    assert cli(["track", str(path), "--json", "--no-progress"]) == 3
    out = capsys.readouterr()
    lines = [json.loads(x) for x in out.out.splitlines()]
    assert len(lines) == 6 and not any(e["detected"] for e in lines)
    assert all(e["range_m"] is None and e["measured_range_m"] is None for e in lines)
    assert "no target signal in any of the 6 frames" in out.err
    path = _noisy_spot(tmp_path, [True, True, True, False, True, True])
    assert cli(["track", str(path), "--json", "--no-progress"]) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert [e["detected"] for e in lines] == [True, True, True, False, True, True]
    assert lines[3]["measured_range_m"] is None
    assert all(abs(e["range_m"] - 1.5) < 0.01 for e in lines)
