"""Study axes checked (issue 59 item 4): two axes on one key, a value twice in one axis (or a
combination twice in a zip, a seed or estimator twice), and a grid step the search cannot score
are refused when the study is loaded, in one line naming the field."""
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nlos_cl.core.errors import InputError
from nlos_cl.sweep import load_study
from nlos_cl.sweep.values import check_grid

BASE = {"setup": {"detector_spots": [[-0.5, 0, 0], [-1, 0, 0], [-1.5, 0, 0]]},
        "targets": [{"shape": "rectangle", "size_m": [0.3, 1.6], "position": [4, 2, 0]}],
        "facet_size_m": 0.02, "time_axis": {"dt_s": 1e-11}, "noise": {"snr_db": 10}}

VALUE = st.one_of(st.integers(-10**6, 10**6), st.floats(-1e6, 1e6, allow_nan=False),
                  st.text(max_size=8), st.lists(st.integers(0, 9), max_size=3))


def _key(v):  # what a run gets: 1 and 1.0 are one value
    return repr(float(v)) if isinstance(v, (int, float)) and not isinstance(v, bool) else repr(v)


@settings(max_examples=150, deadline=None)
@given(values=st.lists(VALUE, min_size=1, max_size=12, unique_by=_key), data=st.data())
def test_a_value_twice_in_an_axis_is_refused(values, data):
    axis = {"path": "description", "name": "d", "values": values}
    assert load_study({"scene": BASE, "axes": [axis]}).n_runs == len(values)
    again = data.draw(st.sampled_from(values))
    if isinstance(again, int) and data.draw(st.booleans()):
        again = float(again)  # 3 and 3.0 set the same value
    at = data.draw(st.integers(0, len(values)))
    twice = {**axis, "values": values[:at] + [again] + values[at:]}
    with pytest.raises(InputError, match=r"^axes\[1\]\.values: holds .* twice .*Fix: give each"):
        load_study({"scene": BASE, "axes": [{"path": "noise.snr_db", "values": [0]}, twice]})


PATHS = st.lists(st.one_of(st.sampled_from(["setup", "noise", "pulse", "a", "b"]),
                           st.integers(0, 2)), min_size=1, max_size=4).map(
    lambda steps: [s for s in steps if not isinstance(s, int)] or ["noise"])


def _text(steps):
    return ".".join(steps)


@settings(max_examples=150, deadline=None)
@given(steps=PATHS, cut=st.integers(1, 4), zipped=st.booleans())
def test_two_axes_on_one_key_or_inside_it_are_refused(steps, cut, zipped):
    """One path, or one a prefix of the other (a whole mapping and a key inside it), crossed or
    zipped: the later axis's field is named."""
    outer = {"path": _text(steps[:cut]), "name": "outer", "values": [{"k": 1}, {"k": 2}]}
    inner = {"path": _text(steps), "name": "inner", "values": [1, 2]}
    axes = ([{"zip": [outer, inner]}] if zipped else [outer, inner])
    where = r"axes\[0\]\.zip\[1\]\.path" if zipped else r"axes\[1\]\.path"
    with pytest.raises(InputError, match=rf"^{where}: sets .*, which axes\[0\].* sets too"):
        load_study({"scene": BASE, "axes": axes})


@pytest.mark.parametrize("study, where", [
    ({"axes": [{"path": "estimator", "name": "e", "values": ["paper", "model"]}]},
     r"^estimators: sets 'estimator', which axes\[0\]\.path"),
    ({"axes": [{"path": "seed", "name": "s", "values": [1, 2]}]}, r"^seeds: sets 'seed'"),
    ({"axes": [{"path": "targets[0].position", "values": [[3, 2, 0]]},
               {"path": "targets[0].position[1]", "name": "y", "values": [1, 2]}]},
     r"^axes\[1\]\.path: sets 'targets\[0\]\.position\[1\]'"),
    ({"seeds": [3, 1, 3]}, r"^seeds: holds 3 twice"),
    ({"estimators": ["paper", "model", "paper"]}, r"^estimators: holds 'paper' twice"),
    ({"axes": [{"zip": [{"path": "noise.snr_db", "values": [0, 0]},
                        {"path": "h_s", "values": [1e-9, 1e-9]}]}]},
     r"^axes\[0\]\.zip: holds \(0, 1e-09\) twice"),
    ({"axes": [{"path": "h_s", "range": {"start": 0, "stop": 1e-12, "step": 1e-13}}]},
     r"^axes\[0\]\.range: holds 0\.0 twice .*below its 1e-12 rounding"),
])
def test_the_red_team_s_axes_are_refused(study, where):
    with pytest.raises(InputError, match=where) as err:
        load_study({"scene": BASE, **study})
    assert "Fix:" in str(err.value) and "\n" not in str(err.value)


def test_a_zip_may_repeat_values_in_distinct_combinations():
    """reproduce beyond's (case, seed) zip repeats each: only a whole combination is one run."""
    study = load_study({"scene": BASE, "axes": [{"zip": [
        {"path": "noise.snr_db", "values": [0, 0, 10, 10]},
        {"path": "h_s", "values": [1e-9, 2e-9, 1e-9, 2e-9]}]}]})
    assert study.n_runs == 4


def test_a_grid_step_the_search_cannot_score_is_refused(monkeypatch):
    """The red team's study: 1e-5 m steps over the paper's plane answered 3.4 m off, exit 0
    (`locate --region` refuses the same grid)."""
    grid = {"x": [0, 6], "y": [0.01, 6], "step_m": 1e-5}
    with pytest.raises(InputError, match=r"^grid\.step_m: makes 3\.59e\+11 cells .*2\^31"):
        load_study({"scene": BASE, "grid": grid})
    for step in (5e-324, 0.0, -0.01, "0.01", True, float("nan")):
        with pytest.raises(InputError, match=r"^grid\.step_m: "):
            check_grid({**grid, "step_m": step})
    for bad in ({"x": [0]}, {"y": ["a", 1]}, {"z": 0}):
        with pytest.raises(InputError, match=rf"^grid\.{next(iter(bad))}: expected \[low, high\]"):
            check_grid({**grid, "step_m": 0.01, **bad})
    monkeypatch.setenv("NLOS_CL_MEMORY_LIMIT", str(2 ** 20))  # the budget, as for --region
    with pytest.raises(InputError, match=r"^grid\.step_m: a score map of .* needs about"):
        check_grid({**grid, "step_m": 0.01})
    monkeypatch.delenv("NLOS_CL_MEMORY_LIMIT")
    assert check_grid({**grid, "step_m": 0.01}) == {**grid, "step_m": 0.01}


def test_the_example_runner_checks_its_step_as_a_study_grid():
    from nlos_cl.sweep.examples import paper_target
    with pytest.raises(InputError, match=r"^grid\.step_m: makes .* cells"):
        paper_target(3.0, 0, step_m=1e-5)
