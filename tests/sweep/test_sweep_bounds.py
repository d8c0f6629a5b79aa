"""Bounded study input (nlos_cl/sweep/bounds.py, issue 59 items 2 and 5): a file a study names
as its scene is never echoed; values are shown in one short line; deep or alias-multiplied
study data end in one line naming the study, within bounded memory and time."""
import resource
import time

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from nlos_cl.core.errors import InputError
from nlos_cl.io import yamlfile
from nlos_cl.sweep import load_study
from nlos_cl.sweep.bounds import MAX_SHOWN, shown
from nlos_cl.sweep.study import check_scenes

# a line of a file the user did not name: a secret's shape (key: value, colon-separated fields,
# a bare word, a YAML-breaking token)
SECRET_LINES = st.lists(st.one_of(
    st.from_regex(r"[a-z_]{3,10}:[!*x]:[0-9]{5}:[0-9]:[0-9]{5}:[0-9]::", fullmatch=True),
    st.from_regex(r"[a-z]{4,12}: [A-Za-z0-9+/]{12,40}", fullmatch=True),
    st.from_regex(r"[A-Z_]{4,12}=[a-z0-9]{8,30}", fullmatch=True),
    st.from_regex(r"[a-z]{4,10}:x:[0-9]{3}:[a-z,]{5,20}", fullmatch=True),
    st.from_regex(r"%[a-z]{6,12} [a-z]{6,12}", fullmatch=True),
    st.from_regex(r"  - [a-z]{8,16}: \[[0-9]{8,12}", fullmatch=True)), min_size=1, max_size=12)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(lines=SECRET_LINES)
def test_a_file_the_study_names_as_its_scene_is_never_echoed(tmp_path, lines):
    secret = tmp_path / "secret"  # no .yaml: as /etc/shadow, /etc/group, ~/.netrc would be
    secret.write_text("\n".join(lines) + "\n")
    try:
        check_scenes(load_study({"scene": str(secret)}))
    except InputError as exc:
        text = str(exc)
        assert "\n" not in text and "Fix:" in text and len(text) < 500
        for line in lines:
            for part in [line, *line.replace("=", ":").split(":")]:
                assert len(part.strip()) < 8 or part.strip() not in text, (part, text)
    else:
        pytest.fail("a secret's lines loaded as a scene")


def test_a_study_naming_system_files_says_where_not_what(tmp_path):
    shadow = tmp_path / "shadow"
    shadow.write_text("rootish:*:20228:0:99999:7:::\nsecretuser:$6$abcdefgh$ijkl:20228:0:99999:7:::\n")
    with pytest.raises(InputError, match=r"^study\.scene: .*is not a scene file \(2 of its 2") \
            as err:
        load_study({"scene": str(shadow)})
    assert "rootish" not in str(err.value) and "secretuser" not in str(err.value)
    group = tmp_path / "group"
    group.write_text("rootish:x:0:\nssl-cert:x:103:postgres\npostgres:x:104:\n")
    with pytest.raises(InputError, match=r"is not a scene file nlos_cl reads \(.*line 3, column 1\)") as err:
        load_study({"scene": str(group)})
    assert "postgres" not in str(err.value) and "ssl-cert" not in str(err.value)


@given(st.recursive(st.one_of(st.text(max_size=50_000), st.integers(), st.floats()),
                    lambda c: st.lists(c, max_size=30) | st.dictionaries(st.text(max_size=40_000), c,
                                                                         max_size=30),
                    max_leaves=60))
@settings(max_examples=80, deadline=None)
def test_shown_is_one_short_line(value):
    text = shown(value)
    assert len(text) <= MAX_SHOWN and "\n" not in text


def _nested(depth: int, kinds: str):
    value = 1
    for i in range(depth):  # built without recursion, as a parser would build it
        value = [value] if kinds[i % len(kinds)] == "l" else {"k": value}
    return value


@settings(max_examples=25, deadline=None)
@given(depth=st.integers(65, 100_000), kinds=st.sampled_from(["l", "d", "ld", "dll"]),
       where=st.sampled_from(["scene", "params", "description"]))
def test_deep_study_data_is_one_line_not_a_recursion_error(depth, kinds, where):
    """From Python (nl.sweep(dict)) a study may be nested without bound; past 64 levels it is
    refused before anything (deepcopy, json, repr) recurses into it."""
    study = ({"runner": "nlos_cl.sweep.examples:paper_target", "axes": [
        {"name": "x", "values": [3.0]}], "seeds": 1, "params": {"y": _nested(depth, kinds)}}
        if where == "params" else {"scene": {}, where: _nested(depth, kinds)})
    with pytest.raises(InputError, match=r"^study: nests lists or mappings more than 64 deep"):
        load_study(study)


@pytest.mark.parametrize("text", ["[" * 100_000 + "]" * 100_000,
                                  '{"scene": ' + "{\"a\": " * 100_000 + "1" + "}" * 100_001])
def test_a_deep_study_json_is_one_line(tmp_path, text):
    """As the study file, and as the record a --resume reads (OUT/study.json)."""
    (tmp_path / "study.json").write_text(text)
    with pytest.raises(InputError, match=r"nests lists or mappings more than 64 deep"):
        load_study(tmp_path / "study.json")
    from nlos_cl.sweep import sweep
    study = {"runner": "nlos_cl.sweep.examples:paper_target", "axes": [
        {"name": "x", "values": [3.0]}], "seeds": 1}
    with pytest.raises(InputError, match=r"study\.json is not readable JSON \(nests too deep\)"):
        sweep(study, tmp_path, workers=0, progress=False, resume=True)


def _peak(fn):
    """(fn's exception or None, peak traced bytes, seconds)."""
    import tracemalloc
    tracemalloc.start()
    start = time.perf_counter()
    try:
        fn()
        caught = None
    except Exception as exc:  # noqa: BLE001 - the test inspects it
        caught = exc
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return caught, peak, time.perf_counter() - start


def _bomb(folder, size: int, count: int):
    values = ", ".join(f"[*a, {k}]" for k in range(count))  # distinct values, each holding *a
    path = folder / "bomb.yaml"
    path.write_text(f"description: &a {'x' * size}\nscene: {{}}\n"
                    f"axes:\n  - {{path: description, name: d, values: [{values}]}}\n")
    return path


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(size=st.integers(1_000, 110_000), count=st.integers(2, 9_000))
def test_an_alias_bomb_is_refused(tmp_path, size, count):
    """One long text aliased many times: the YAML reader bounds what aliases add (10,000 nodes,
    1 MiB of text: io.yamlfile), the study what its data expand to (MAX_STUDY_BYTES, for
    studies built in Python): no 900 MB message or study.json."""
    added = size * count  # the text the aliases add
    assume(abs(added - yamlfile.MAX_BYTES) > 0.02 * yamlfile.MAX_BYTES)  # not on the edge
    path = _bomb(tmp_path, size, count)
    if added > yamlfile.MAX_BYTES:
        with pytest.raises(InputError, match=r"^study file .*: (its aliases )?expands? to more "
                                             r"than") as err:
            load_study(path)
        assert len(str(err.value)) < 400
    else:
        assert load_study(path).n_runs == count


def test_the_red_team_s_alias_bomb_within_bounded_memory(tmp_path):
    """100 kB aliased 9,000 times (900 MB expanded): refused, peak Python memory ~16 MB."""
    caught, peak, seconds = _peak(lambda: load_study(_bomb(tmp_path, 100_000, 9_000)))
    assert isinstance(caught, InputError) and "expand" in str(caught) and "more than" in \
        str(caught)
    assert peak < 64 << 20 and seconds < 60  # nothing is expanded (the reader's pace: ~2 s)


def test_shared_references_from_python_are_counted_as_expanded():
    big = "y" * (1 << 20)
    study = {"scene": {}, "axes": [{"path": "description", "values": [[big] * 64, [big] * 65]}]}
    caught, peak, seconds = _peak(lambda: load_study(study))
    assert isinstance(caught, InputError) and "expands to more than" in str(caught)
    assert peak < 16 << 20 and seconds < 5
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss < 4 << 20  # KiB: under 4 GiB


@pytest.mark.parametrize("change", [
    {"targets": [{"shape": "q" * 100_000}]}, {"noise": {"snr_db": "q" * 100_000}},
    {"q" * 100_000: 1}, {"setup": {"detector_spots": "q" * 100_000}}])
def test_a_scene_check_quoting_a_long_value_stays_one_short_line(change):
    scene = {"setup": {"detector_spots": [[-0.5, 0, 0], [-1, 0, 0]]},
             "targets": [{"shape": "rectangle", "size_m": [0.3, 1.6], "position": [4, 2, 0]}]}
    with pytest.raises(InputError, match=r"^study axes .* Fix: ") as err:
        check_scenes(load_study({"scene": {**scene, **change}}))
    assert len(str(err.value)) <= 400 and "\n" not in str(err.value)
