"""Births and deaths from the data (tracking.births): with targets='auto' the tracker finds how
many targets a sequence holds, and a plate the data do not hold is no measurement."""
from types import SimpleNamespace

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.tracking.births import BIRTH_FRAMES, COOL_FRAMES, LEFTOVER, TargetCount, supported


def _track(status):
    return SimpleNamespace(status=status)


def _location(left: bool):
    fit = SimpleNamespace(warnings=(LEFTOVER + " ...",) if left else ())
    return SimpleNamespace(targets=[SimpleNamespace(fit=fit)])


def test_the_count_is_auto_while_no_track_lives_then_the_live_tracks():
    """'auto' (up to the cap) only while nothing is followed; tentative tracks count (their
    birth is confirmed by a warm fit of that many plates, not a cold 'auto' fit)."""
    count = TargetCount(3)
    assert count.for_frame([]) == ("auto", 3)
    assert count.for_frame([_track("deleted")]) == ("auto", 3)
    assert count.for_frame([_track("confirmed"), _track("tentative")]) == (2, 2)
    assert count.for_frame([_track("tentative")]) == (1, 1)
    assert count.for_frame([_track("confirmed")] * 4) == (3, 3)


def test_one_more_is_tried_after_a_run_of_residual_returns_then_cools_down():
    count = TargetCount(3)
    tries = [count.try_more(_location(True), 1) for _ in range(BIRTH_FRAMES)]
    assert tries == [False] * (BIRTH_FRAMES - 1) + [True]
    count.tried(found_more=False)
    assert not any(count.try_more(_location(True), 1) for _ in range(COOL_FRAMES - 1))
    assert not count.try_more(_location(True), 3)  # at the cap: never
    assert not count.try_more(_location(False), 1)  # a clean residual resets the run


def test_the_auto_refit_runs_at_a_bounded_rate_whatever_it_found():
    """A residual that holds a return every frame (a shape the model lacks) sends at most
    one frame in COOL_FRAMES + 1 to the 'auto' refit, also where the refit found more (what
    it found was a tentative track that died: the refit came back two frames later)."""
    count = TargetCount(3)
    fired = []
    for _ in range(60):
        fired.append(count.try_more(_location(True), 1))
        if fired[-1]:
            count.tried(found_more=True)
    assert 0 < sum(fired) <= -(-60 // (COOL_FRAMES + 1))


def test_a_plate_the_data_do_not_hold_is_no_measurement():
    def m(support):
        return SimpleNamespace(source=SimpleNamespace(fit=SimpleNamespace(
            diagnostics={"support": support})))
    kept = supported([m(12.0), m(-3.0), m(None), SimpleNamespace(source=None)])
    assert len(kept) == 3 and all(getattr(k.source, "fit", None) is None or
                                  k.source.fit.diagnostics["support"] != -3.0 for k in kept)


@pytest.fixture(scope="module")
def two_squares(tmp_path_factory):
    """Two 0.4 m squares 1.5 m apart walking slowly, 8 spots on a circle, 10 dB, 8 frames."""
    from nlos_cl.physics import layouts
    from nlos_cl.tracking import MovingTarget, Trajectory, simulate_sequence
    setup = nl.paper_setup(detector_spots=layouts.circle((-1.0, 0.0, 0.0), 0.5, 8))
    paths = [Trajectory([0, 0.7], [[3.2, 1.6, 0], [3.2, 1.9, 0]]),
             Trajectory([0, 0.7], [[1.8, 3.0, 0], [2.1, 3.0, 0]])]
    moving = [MovingTarget(nl.Target(nl.rectangle(0.4, 0.4, centre=p.at(0), normal=n,
                                                  cell_m=0.03)), p)
              for p, n in zip(paths, [(-1.0, -0.6, 0.0), (-1.0, -1.0, 0.0)])]
    frames = simulate_sequence(setup, moving, n_frames=8, fps=10, noise=nl.AWGN(10), seed=2,
                               facet_size_m=0.03, time_axis=nl.default_time_axis(setup, 1e-11))
    return nl.write_sequence(tmp_path_factory.mktemp("two") / "two.h5", frames)


def test_auto_finds_both_targets_and_follows_each_with_one_id(two_squares):
    """With the default (targets='auto') both squares get a confirmed track by frame 3 and
    keep their id; targets=1 follows one of them only."""
    steps = list(nl.track_sequence(two_squares))
    last = steps[-1]
    confirmed = [t for t in last.tracks if t.status == "confirmed"]
    assert len(confirmed) == 2
    for step in steps[3:]:
        truths = step.frame.truths
        ours = {t.id: t.position for t in step.tracks if t.status == "confirmed"}
        assert len(ours) == 2
        for truth in truths:
            nearest = min(ours, key=lambda i: np.linalg.norm(ours[i] - truth))
            assert np.linalg.norm(ours[nearest] - truth) < 0.1
    ids = {t.id for s in steps[3:] for t in s.tracks}
    assert len(ids) == 2
    one = list(nl.track_sequence(two_squares, targets=1))[-1]
    assert len(one.tracks) == 1


def test_auto_keeps_one_id_on_one_walker(walk_file):
    """The conftest walk (one plate, 12 frames): 'auto' follows it with one id, as 1 does."""
    steps = list(nl.track_sequence(walk_file, targets="auto"))
    assert {t.id for s in steps for t in s.tracks} == {1}
    errors = [np.linalg.norm(s.tracks[0].position - s.frame.truths[0]) for s in steps[3:]]
    assert np.median(errors) < 0.05
