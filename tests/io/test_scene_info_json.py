"""scene_info as nlos_cl writes it (issue 23 item 4): JSON that PyYAML (y-tal's reader), nlos_cl's
YAML reader and a JSON parser all read to the same values, so that reading a capture needs no
PyYAML; and the NumPy helpers that keep numpy.ma out of a one-shot locate give NumPy's numbers."""
import json
import math
import subprocess
import sys
import textwrap

import h5py
import numpy as np
import pytest
import yaml

import nlos_cl as nl
from error_catalogue import capture_file
from nlos_cl.apps import cli
from nlos_cl.core.stats import median, unique_sorted
from nlos_cl.io.scenefile import yaml_loader
from nlos_cl.io.yamlfile import dump_json_yaml, load_json_yaml

AWKWARD = {"tiny": 1e-11, "huge": 1e20, "neg": -2.5e-300, "whole": 3.0, "int": 7, "big": 2**70,
           "flags": [True, False, None], "text": 'a "quoted" line\nwith \\ and é and 1e5',
           "number_like": "1e-11", "nested": {"t": (0.1, 2e-7), "empty": [], "none": {}},
           "np": [np.float32(0.25), np.float64(1e-11), np.int64(3), np.bool_(True)]}


def _plain(value):
    """What every reader should give back: tuples as lists, NumPy scalars as Python's."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value.item() if isinstance(value, np.generic) else value


def test_every_reader_reads_the_same_values():
    text = dump_json_yaml(AWKWARD)
    assert text.startswith("{") and text.count("\n") == 1, "written as one JSON line"
    expected = _plain(AWKWARD)
    assert json.loads(text) == expected
    assert yaml.safe_load(text) == expected  # PyYAML's YAML 1.1, as y-tal reads scene_info
    assert yaml.load(text, Loader=yaml_loader()) == expected  # noqa: S506 - nlos_cl's reader
    assert load_json_yaml(text) == expected
    assert "1.0e-11" in text and "1.0e+20" in text  # YAML 1.1 reads 1e-11 as text


@pytest.mark.parametrize("value", [math.nan, math.inf, {1: "int key"}, b"bytes", {"s": {1, 2}},
                                   "\U0001F600"])
def test_what_json_cannot_carry_is_written_as_yaml(value):
    """NaN, infinities, non-text keys and other types fall back to PyYAML's block style (or
    fail as PyYAML's safe_dump does); an emoji survives as JSON or as YAML, never mangled."""
    data = {"v": value}
    try:
        text = dump_json_yaml(data)
    except yaml.YAMLError:
        return  # safe_dump refuses it too (a set): nothing silently changed
    back = yaml.safe_load(text)["v"]
    assert back == value or (isinstance(value, float) and math.isnan(back))


@pytest.mark.parametrize("text", ['{"a": 1, "a": 2}', '{"a": NaN}', '{"a": Infinity}',
                                  "a: 1\n", "[1, 2]", "{" * 5000 + "}" * 5000, "{broken",
                                  '{"a": ' + "[" * 64 + "]" * 64 + "}",  # 65 deep
                                  '{"a": ' + "[" * 499 + "]" * 499 + "}"])  # 500 deep
def test_what_is_not_plain_json_goes_to_the_yaml_reader(text):
    """Duplicate keys, NaN, not a JSON object, nesting beyond the YAML reader's MAX_DEPTH (64):
    None, so that the YAML reader decides (and refuses the last in one line)."""
    assert load_json_yaml(text) is None


def test_json_as_deep_as_the_yaml_reader_allows_is_read():
    text = '{"a": ' + "[" * 63 + "]" * 63 + "}"  # 64 deep: the bound itself
    assert load_json_yaml(text) is not None
    assert load_json_yaml(text) == yaml.load(text, Loader=yaml_loader())  # noqa: S506


def test_deep_json_scene_info_is_refused_in_one_line(tmp_path):
    def deep(f):
        del f["scene_info"]
        f["scene_info"] = '{"original_format": "nlos_cl", "nlos_cl": ' + "[" * 200 + \
            "]" * 200 + "}"
    with pytest.raises(nl.InputError, match="scene_info: nests lists or mappings more than 64"):
        nl.read_capture(capture_file(deep))


def test_text_beyond_the_basic_plane_stays_json():
    """An emoji or a CJK name: written raw as UTF-8 (PyYAML does not join json's escaped
    surrogate pairs, which would send the text to block YAML and the reader back to PyYAML)."""
    data = {"name": "plaque \U0001F600 標的", "n": 1}
    text = dump_json_yaml(data)
    assert text.startswith("{") and yaml.safe_load(text) == data == load_json_yaml(text)


def test_a_key_twice_in_json_scene_info_is_refused_by_the_yaml_reader(tmp_path):
    def twice(f):
        info = f["scene_info"][()].decode()
        assert info.startswith("{")
        del f["scene_info"]
        f["scene_info"] = info.replace('{"original_format": "nlos_cl",',
                                       '{"nlos_cl": {}, "original_format": "nlos_cl",', 1)
    with pytest.raises(nl.InputError, match="scene_info: the key 'nlos_cl' appears twice"):
        nl.read_capture(capture_file(twice))


def test_older_block_yaml_scene_info_reads_the_same(tmp_path):
    """Captures written before scene_info was JSON (PyYAML's block style) read as before."""
    new = capture_file()
    old = tmp_path / "old.h5"
    with h5py.File(new, "r") as a, h5py.File(old, "w") as b:
        for key in a:
            a.copy(a[key], b, name=key)
        del b["scene_info"]
        b["scene_info"] = yaml.safe_dump(yaml.safe_load(a["scene_info"][()]))
    h_new, h_old = nl.read_capture(new)[0], nl.read_capture(old)[0]
    assert h_old.time_axis == h_new.time_axis and h_old.truth == h_new.truth
    np.testing.assert_array_equal(h_old.calibration.b_m, h_new.calibration.b_m)


def test_a_one_shot_locate_imports_neither_pyyaml_nor_numpy_ma(tmp_path):
    """~20 ms of a one-shot `nlos-cl locate` (issue 23 item 4): reading our scene_info needs no
    PyYAML, and np.unique/np.median (which import numpy.ma on their first call in NumPy 2.x)
    are kept off the locate's path. A new np.median or np.unique there fails this test."""
    path = tmp_path / "c.h5"  # `nlos-cl simulate`'s window holds the direct wall return too
    cli.main(["simulate", "--out", str(path), "--facet", "0.05", "--snr-db", "10"])
    code = textwrap.dedent(f"""
        import sys, nlos_cl as nl
        nl.locate_capture({str(path)!r})
        print(sorted(m for m in ('yaml', 'numpy.ma', 'statistics') if m in sys.modules))
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


@pytest.mark.parametrize("shape", [(0,), (1,), (7,), (8,), (3, 5), (1000,)])
def test_median_and_unique_are_numpys(shape):
    """The same numbers as NumPy's, bit for bit: float64, float32 (np.median averages the
    middle two in float32), integers, NaNs (unique keeps one, as np.unique's equal_nan)."""
    rng = np.random.default_rng(sum(shape))
    for values in (rng.normal(size=shape), rng.normal(size=shape).astype(np.float32),
                   rng.integers(0, 4, size=shape), rng.integers(0, 4, size=shape) * 0.5):
        np.testing.assert_array_equal(unique_sorted(values), np.unique(values))
        if values.size:
            assert median(values) == float(np.median(values))
    assert median(np.array([1, 1 + 2 ** -23], np.float32)) == 1.0  # float32's own mean
    assert math.isnan(median([1.0, math.nan, 2.0]))
    with_nans = np.array([np.nan, 1.0, np.nan, 2.0, 1.0])
    np.testing.assert_array_equal(unique_sorted(with_nans), np.unique(with_nans))
