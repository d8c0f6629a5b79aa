"""The consumer-nlos walk (measured, MIT; ../shared/realdata, skipped where absent) tracked with
no option: the static returns learned from the sequence (tracking.static) leave zones dark
where the person is not, and the track must still run. The first version asked the argmax
whether the learned background held a target and raised 'no cell has a non-zero likelihood'
before frame 0."""
from pathlib import Path

import numpy as np
import pytest

import nlos_cl as nl

WALK = Path(__file__).resolve().parents[3] / "shared" / "realdata" / "consumer-nlos" / \
    "st_spad_person_tracking"


def test_the_walk_is_tracked_with_no_option(tmp_path):
    if not WALK.is_dir():
        pytest.skip("../shared/realdata/consumer-nlos is absent")
    from nlos_cl.apps import cli
    out = tmp_path / "walk.h5"
    assert cli.main(["convert", str(WALK), "--out", str(out)]) == 0
    with pytest.warns(UserWarning):
        steps = list(nl.track_sequence(out, max_frames=40))
    assert len(steps) == 40
    assert any(step.tracks for step in steps[10:])
    for step in steps:
        for track in step.tracks:
            assert np.all(np.isfinite(track.position))
