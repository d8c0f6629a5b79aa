"""Rival shapes (model.policy.rivals): another closed family within RIVAL_UNITS of the chosen
fit's cost whose centre lies farther than RIVAL_DISTANCE_M is reported, and the answer warns.
The rule on made-up fits (every combination of cost gap and distance, several targets); on the
scenario suite's draws: tests/apps/test_scenario_draws.py."""
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from nlos_cl.localization.model.policy.rivals import (CENTRE_RIVALS_KEY, RIVAL_DISTANCE_M,
                                                      RIVAL_UNITS, RIVALS_KEY, centre_note,
                                                      rival_note, rivals)


def _fit(cost, *centres):
    return SimpleNamespace(cost=cost, params=np.array([[*c, 0.5, 1.7, 0.3, 0.0]
                                                        for c in centres], float))


@settings(max_examples=200, deadline=None)
@given(gap=st.floats(-5.0, 3.0 * RIVAL_UNITS), unit=st.floats(0.5, 50.0),
       shift=st.floats(0.0, 1.0), axis=st.integers(0, 2))
def test_a_rival_is_reported_exactly_when_close_in_cost_and_far_in_centre(gap, unit, shift,
                                                                           axis):
    chosen = _fit(100.0, (1.0, 3.0, 0.2))
    centre = np.array([1.0, 3.0, 0.2])
    centre[axis] += shift
    other = _fit(100.0 + gap * unit, centre)
    found = rivals([("ellipsoid", chosen), ("cylinder", other)], "ellipsoid", chosen, unit)
    expected = gap <= RIVAL_UNITS and shift > RIVAL_DISTANCE_M
    assert bool(found) == expected
    note = rival_note({RIVALS_KEY: found}, 0, 0)
    assert (note is not None) == expected
    if expected:
        assert found[0]["shape"] == "cylinder" and "target 1" in note and "cylinder" in note
        assert found[0]["distance_m"][0] == pytest.approx(shift)


def test_each_target_is_judged_by_its_own_centre_and_the_farthest_rival_is_named():
    chosen = _fit(10.0, (0.0, 3.0, 0.0), (1.0, 4.0, 0.0))
    near_first = _fit(12.0, (0.05, 3.0, 0.0), (1.0, 4.4, 0.0))  # target 2 0.4 m away
    farther = _fit(14.0, (0.0, 3.0, 0.0), (1.0, 4.7, 0.0))  # target 2 0.7 m away
    ruled_out = _fit(10.0 + 11.0, (0.0, 2.0, 0.0), (1.0, 4.0, 0.0))
    info = {RIVALS_KEY: rivals([("box", chosen), ("ellipsoid", near_first),
                                ("cylinder", farther), ("capsule", ruled_out)],
                               "box", chosen, 1.0)}
    assert [r["shape"] for r in info[RIVALS_KEY]] == ["ellipsoid", "cylinder"]
    assert rival_note(info, 0, 0) is None  # target 1: no rival moves it 0.15 m
    note = rival_note(info, 1, 0)  # target 2, reported first
    assert note.startswith("the shape of target 1") and "cylinder" in note and "0.70 m" in note


def test_no_rivals_key_no_note():
    assert rival_note({}, 0, 0) is None


@settings(max_examples=100, deadline=None)
@given(units=st.lists(st.floats(-2.0, 3.0 * RIVAL_UNITS), min_size=0, max_size=4))
def test_a_held_centre_within_the_rival_line_is_said_the_cheapest_named(units):
    """centre_note: the one target's centre held RIVAL_DISTANCE_M away (closed.centre_profile)
    warns exactly where some such point costs at most RIVAL_UNITS more; the cheapest is
    named; a family rival is said first (rival_note), and no other target gets it."""
    names = ["least certain", "least certain", "line of sight", "line of sight"]
    points = [{"direction": names[i], "offset_m": (-1) ** i * RIVAL_DISTANCE_M, "units": u}
              for i, u in enumerate(units)]
    info = {CENTRE_RIVALS_KEY: points}
    note = rival_note(info, 0, 0)
    near = [p for p in points if p["units"] <= RIVAL_UNITS]
    assert (note is not None) == bool(near) and note == centre_note(info, 0, 0)
    if near:
        cheapest = min(near, key=lambda p: p["units"])
        assert note.startswith("the position of target 1 is poorly determined")
        assert f"{max(cheapest['units'], 0.0):.1f} units" in note and "0.15 m away" in note
        assert ("line of sight" in note) == (cheapest["direction"] == "line of sight")
    assert centre_note(info, 1, 1) is None
    rival = _fit(1.0, (0.0, 3.5, 0.0))
    both = dict(info, **{RIVALS_KEY: rivals([("box", _fit(1.0, (0.0, 3.0, 0.0))),
                                             ("capsule", rival)], "box",
                                            _fit(1.0, (0.0, 3.0, 0.0)), 1.0)})
    assert rival_note(both, 0, 0).startswith("the shape of target 1 is ambiguous")
