"""Issue 59 item 5: error messages are bounded in size. Every value a message echoes goes
through nlos_cl.core.errors.shown (one line, at most ~60 characters and its length), and the
YAML reader names a problem's line and column instead of quoting the line (a line may be one
100 kB value)."""
import h5py
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.core.errors import InputError, shown
from nlos_cl.io.yamlfile import load_text, whole_number

BIG = "v" * 100_000


@pytest.mark.parametrize("value", [BIG, BIG.encode(), np.zeros((1000, 1000)),
                                   [[BIG] * 10] * 10, {"k": BIG}, "a\nb\n" * 1000])
def test_shown_is_one_short_line(value):
    text = shown(value)
    assert "\n" not in text and len(text) <= 90, text


def test_shown_keeps_short_values_whole():
    assert shown("paper") == "'paper'" and shown(2.5) == "2.5" and shown([1, 2]) == "[1, 2]"


def bounded(exc):
    text = str(exc)
    assert "\n" not in text and len(text) < 400 and "v" * 100 not in text, text[:500]
    assert "Fix:" in text, text
    return text


@pytest.mark.parametrize("yaml_text, says", [
    (f"? {BIG}\n: 1\n? {BIG}\n: 2\n", "appears twice"),  # a 100 kB key, twice
    (f"a: [1, 2\nb: {BIG}\n", "on line 2"),  # a syntax error on a 100 kB line
    (f"a: *{BIG}\n", "undefined alias"),  # a 100 kB alias name
    (f"a: &{BIG} [1]\nb: *{BIG}\nc: !!python/object:os.system {BIG}\n", "line 3"),
])
def test_yaml_errors_echo_no_long_value(yaml_text, says):
    with pytest.raises(InputError) as info:
        load_text(yaml_text, "study s.yaml")
    assert says in bounded(info.value)


def test_a_whole_number_field_echoes_a_short_value():
    with pytest.raises(InputError) as info:
        whole_number("study s.yaml: workers", BIG)
    assert "(100,000 characters)" in bounded(info.value)


@pytest.mark.parametrize("field, value", [
    ("H_format", np.array([BIG[:1000]] * 50, dtype=object)),  # was a multi-line array repr
    ("delta_t", np.array([BIG[:5000]], dtype=object)),
    ("t_accounts_first_and_last_bounces", np.array(BIG.encode())),
])
def test_capture_fields_echo_a_short_value(tmp_path, field, value):
    data = 1.0 + np.arange(600.0).reshape(3, 200) % 7
    h = nl.HistogramSet(data, nl.TimeAxis(2 * 20 / nl.SPEED_OF_LIGHT, 10e-12, 200),
                        [[-0.5, 0, 0], [-1, 0, 0], [-1.5, 0, 0]], [0, 0, 0],
                        nl.PathCalibration(nl.SPEED_OF_LIGHT, [-40.0]))
    path = nl.write_capture(tmp_path / "c.h5", h)
    with h5py.File(path, "a") as f:
        del f[field]
        f.create_dataset(field, data=value, **({"dtype": h5py.string_dtype()}
                                               if value.dtype == object else {}))
    with pytest.raises(InputError) as info:
        nl.read_capture(path)
    assert field in bounded(info.value)
