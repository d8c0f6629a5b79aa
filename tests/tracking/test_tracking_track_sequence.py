"""nl.track_sequence: the library's one way to track a sequence (the CLI, reproduce, the bench
and scripts build their trackers through it), and the one estimator-choice policy beside the
registry (localization.estimators.choose_estimator)."""
import warnings

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.localization.estimators import (
    PAIRED_LOCATE_NOTE,
    PAIRED_TRACK_NOTES,
    choose_estimator,
    estimator_names,
)
from nlos_cl.tracking import ConstantVelocity, Interacting, read_sequence
from nlos_cl.tracking.sequences import motion_for


def test_a_run_tracks_once_and_refuses_what_is_not_a_sequence(walk_file):
    run = nl.track_sequence(read_sequence(walk_file), estimator="paper", max_frames=2)
    assert len(list(run)) == 2
    with pytest.raises(nl.InputError, match="track_sequence: a run's frames are tracked once"):
        list(run)
    with pytest.raises(nl.InputError, match="source: expected a sequence file's path"):
        nl.track_sequence(42)


def test_motion_for_names_the_options_as_the_caller_writes_them():
    assert motion_for() == Interacting(accel_sigmas=(0.05, 0.5))
    assert motion_for("cv", accel=0.3) == ConstantVelocity(0.3)
    with pytest.raises(nl.InputError, match=r"steady_accel: must be below accel .*steady_accel="
                       r"0.05, accel=0.5, or motion='cv'"):
        motion_for(steady_accel=1.0)
    with pytest.raises(nl.InputError, match="motion: unknown motion 'ca'"):
        motion_for("ca")


def test_the_default_estimator_follows_the_capture():
    """One layout, one policy: the model fit, except for paired and confocal captures (the
    paper's argmax when locating; the likelihood's mean when tracking one target, its argmax
    with several), each with its note; a reflectance is the model fit's."""
    model, note = choose_estimator()
    assert model.name == "model" and note is None
    assert choose_estimator(targets=2)[0].targets == 2
    est, note = choose_estimator(paired=True)
    assert est.name == "paper" and note == PAIRED_LOCATE_NOTE
    est, note = choose_estimator(paired=True, tracking=True)
    assert est.name == "mean" and note == PAIRED_TRACK_NOTES["mean"]
    est, note = choose_estimator(paired=True, tracking=True, targets=2)
    assert est.name == "paper" and note == PAIRED_TRACK_NOTES["paper"]
    est, note = choose_estimator(paired=True, reflectance=nl.GGX(0.3))
    assert est.name == "model" and note is None
    assert choose_estimator("paper", paired=True)[0].name == "paper"
    with pytest.raises(nl.InputError, match="reflectance: is for the model fit"):
        choose_estimator("paper", reflectance=nl.GGX(0.3))
    with pytest.raises(nl.InputError, match="estimator: mean gives one position"):
        choose_estimator("mean", targets=2, tracking=True)
    with pytest.raises(nl.InputError, match="estimator: unknown name"):
        choose_estimator("centroid")
    assert estimator_names() == ["mean", "model", "paper"]


def test_the_tracker_warns_where_the_default_is_not_the_model_fit(tmp_path):
    """A paired capture's sequence is tracked with the likelihood's mean, and says so."""
    from test_tracking_sequence import _hist

    from nlos_cl.tracking import write_sequence
    frames = []
    for k in range(3):
        h = _hist(k, truth=False)
        spots = np.array(h.detector_spots) + [0, 0.001, 0]  # each spot its own laser point
        frames.append((0.1 * k, nl.HistogramSet(h.data, h.time_axis, h.detector_spots, spots,
                                                h.calibration)))
    path = write_sequence(tmp_path / "paired.h5", frames)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run = nl.track_sequence(path)
    assert run.tracker.estimator.name == "mean"
    assert [str(w.message) for w in caught] == [PAIRED_TRACK_NOTES["mean"]]
