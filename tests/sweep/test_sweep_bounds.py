"""Bounded study input (nlos_cl/sweep/bounds.py, issue 59 items 2 and 5): a file a study names
as its scene is never echoed; values are shown in one short line; deep or alias-multiplied
study data end in one line naming the study, within bounded memory and time."""
import json
import resource
import time

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nlos_cl.core.errors import InputError
from nlos_cl.sweep import load_study
from nlos_cl.sweep.bounds import MAX_SHOWN, MAX_STUDY_BYTES, shown
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
