"""Simulated sequences tracked end to end: a straight line (the tracked error at most half the
per-frame error), and a static box removed by the background reference."""
import warnings

import numpy as np

import nlos_cl as nl
from nlos_cl.tracking import (BackgroundRemover, ConstantVelocity, MovingTarget, Tracker,
                              Trajectory, read_sequence, simulate_sequence, write_sequence)

FACET = 0.03


def _moving(start, stop, duration=3.0):
    mesh = nl.rectangle(centre=start, cell_m=FACET)
    return MovingTarget(nl.Target(mesh), Trajectory([0, duration], [start, stop]))


def _rms(errors):
    return float(np.sqrt(np.mean(np.square(errors))))


def test_straight_line_tracked_error_is_at_most_half(tmp_path):
    setup = nl.paper_setup()
    axis = nl.default_time_axis(setup, 10e-12)
    frames = simulate_sequence(setup, _moving((3, 1.5, 0), (4, 3, 0), 5.0), n_frames=40, fps=10,
                               noise=nl.AWGN(0), seed=2, facet_size_m=FACET, time_axis=axis)
    path = write_sequence(tmp_path / "line.h5", frames)  # through the file format
    seq = read_sequence(path)
    grid = nl.Grid.from_ranges(x=(2, 5), y=(0.5, 4), step_m=0.01)
    tracker = Tracker(seq, grid, estimator="model", motion=ConstantVelocity(accel_sigma=0.02))
    raw, tracked = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # collinear spots: height unobservable
        for frame in seq:
            (track,) = tracker.update(frame.histograms, frame.t_s)
            if frame.index >= 5:
                truth = frame.truths[0][:2]
                raw.append(np.linalg.norm(tracker.last_measurements[0].position[:2] - truth))
                tracked.append(np.linalg.norm(track.position[:2] - truth))
    assert track.id == 1 and track.status == "confirmed"
    assert _rms(tracked) <= 0.5 * _rms(raw), (_rms(tracked), _rms(raw))


def test_static_box_removed_by_a_reference(runtime):
    setup = nl.paper_setup()
    axis = nl.default_time_axis(setup, 10e-12)
    box = nl.Target(nl.box((0.4, 0.4, 1.0), centre=(2.0, 1.2, 0), cell_m=0.05))
    kw = dict(n_frames=8, fps=10, facet_size_m=FACET, time_axis=axis, backend=runtime)
    moving = _moving((3.5, 2.5, 0), (4.0, 3.0, 0), 1.0)
    with_box = simulate_sequence(setup, moving, static=[box], noise=nl.AWGN(10), seed=1, **kw)
    reference = nl.simulate(nl.Scene(setup, box, FACET), axis, backend=runtime)
    grid = nl.Grid.from_ranges(x=(1, 5), y=(0.5, 4), step_m=0.02)
    plain = Tracker(reference, grid, backend=runtime)
    cleaned = Tracker(reference, grid, background=BackgroundRemover(reference), backend=runtime)
    for frame in with_box:
        (a,), (b,) = plain.update(frame.signals, frame.t_s), cleaned.update(frame.signals,
                                                                             frame.t_s)
    truth = frame.truths[0][:2]
    assert np.linalg.norm(b.position[:2] - truth) < 0.15  # the moving target
    assert np.linalg.norm(a.position[:2] - truth) > 0.5  # without removal: the box
