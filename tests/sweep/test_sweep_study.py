"""The study format: paths, axes (values, ranges, zip), runs and their ids, bad input. No Dask."""
import json

import pytest

from nlos_cl.core.errors import InputError
from nlos_cl.sweep import load_study
from nlos_cl.sweep.engine import make_batches
from nlos_cl.sweep.study import assignments, check_scenes, parse_path, scene_of, substitute

BASE = {"setup": {"detector_spots": [[-0.5, 0, 0], [-1, 0, 0], [-1.5, 0, 0]]},
        "targets": [{"shape": "rectangle", "size_m": [0.3, 1.6], "position": [4, 2, 0]}],
        "facet_size_m": 0.02, "time_axis": {"dt_s": 1e-11}, "noise": {"snr_db": 10}}


def study(**extra):
    return {"scene": BASE, **extra}


def test_paths_address_keys_and_indices():
    assert parse_path("targets[0].position[1]") == ["targets", 0, "position", 1]
    scene = substitute(BASE, [("targets[0].position[1]", 3.5), ("noise.snr_db", 0),
                              ("setup.pulse.fwhm_s", 35e-12)])
    assert scene["targets"][0]["position"] == [4, 3.5, 0]
    assert scene["noise"]["snr_db"] == 0 and scene["setup"]["pulse"] == {"fwhm_s": 35e-12}
    assert BASE["targets"][0]["position"] == [4, 2, 0]  # the base is not modified
    with pytest.raises(InputError, match=r"targets\[3\]"):
        substitute(BASE, [("targets[3].position", [1, 1, 0])])


def test_axes_cross_zip_ranges_and_stable_ids():
    s = load_study(study(
        axes=[{"path": "targets[0].position[0]", "name": "x", "range": {"start": 2, "stop": 4,
                                                                       "step": 1}},
              {"zip": [{"path": "h_s", "values": [0.3e-9, 0.65e-9]},
                       {"path": "noise.snr_db", "name": "snr", "range": {"start": 0, "stop": 10,
                                                                         "num": 2}}]}],
        estimators=["paper", "model"], seeds={"start": 5, "count": 2}))
    runs = list(s.runs())
    assert s.n_runs == len(runs) == 3 * 2 * 2 * 2
    assert [r[0] for r in runs] == list(range(24))
    assert runs[0][1] == {"x": 2.0, "h_s": 0.3e-9, "snr": 0.0, "estimator": "paper", "seed": 5}
    assert runs[1][1]["seed"] == 6 and runs[2][1]["estimator"] == "model"
    assert runs[4][1]["h_s"] == 0.65e-9 and runs[4][1]["snr"] == 10.0  # zipped together
    assert scene_of(s.plan(), runs[23][1])["targets"][0]["position"] == [4.0, 2, 0]
    assert s.fingerprint() == load_study(s.as_dict()).fingerprint()
    assert check_scenes(s) >= 3


def test_batches_keep_a_scene_together():
    s = load_study(study(axes=[{"path": "noise.snr_db", "values": [0, 10]},
                               {"path": "targets[0].position[0]", "name": "x",
                                "values": [2, 3]}], seeds=3))
    batches = make_batches(s, list(s.runs()), 6, 2)
    for batch in batches:  # runs of one simulated scene (x) share a batch; SNR does not matter
        assert len({values["x"] for _, values in batch}) == 1
    assert sorted(r for b in batches for r, _ in b) == list(range(12))


@pytest.mark.parametrize("bad, where", [
    ({"axes": [{"path": "noise.snr_db"}]}, "exactly one of values, range"),
    ({"axes": [{"path": "estimator", "values": ["best"]}]}, "unknown estimator"),
    ({"axes": [{"zip": [{"path": "h_s", "values": [1e-9]},
                        {"path": "seed", "values": [1, 2]}]}]}, "differ in length"),
    ({"axes": [{"path": "targets[0].radius_m", "values": [0.3]}]}, "targets"),
    ({"seeds": -1}, "seeds"),
    ({"record": ["everything"]}, "record"),
    ({"filters": "gauss"}, "study.filters"),
    ({"axes": [{"path": "noise.snr_db", "name": "seed", "values": [1]}]}, "used twice"),
    ({"axes": [{"path": "filter", "values": ["gauss"], "scale": 2}]}, r"axes\[0\]\.scale"),
    ({"axes": [{"path": "h_s", "values": [1, "a"], "scale": 1e-9}]}, "needs numeric values"),
    ({"axes": [{"path": "h_s", "values": [1], "scale": "ns"}]}, "nested"),
    ({"axes": [{"path": "h_s", "values": [1], "scale": [[1, True]]}]}, "nested"),
    ({"axes": [{"path": "h_s", "values": [1], "scale": []}]}, "nested"),
])
def test_bad_studies_say_where(bad, where):
    with pytest.raises(InputError, match=where):
        check_scenes(load_study(study(**bad)))


def test_study_file_with_scene_file(tmp_path):
    (tmp_path / "scene.yaml").write_text(json.dumps(BASE))
    (tmp_path / "study.yaml").write_text("scene: scene.yaml\naxes:\n"
                                         "  - {path: noise.snr_db, values: [0, 5]}\n")
    s = load_study(tmp_path / "study.yaml")
    assert s.base == BASE and s.n_runs == 2


def test_scale_sets_value_times_scale_and_keeps_the_value():
    s = load_study(study(axes=[
        {"path": "setup.detector_spots", "name": "delta_m", "values": [0.3, 0.7],
         "scale": [[-1, 0, 0], [-2, 0, 0], [-3, 0, 0]]},
        {"path": "h_s", "name": "h_ns", "values": [0.65], "scale": 1e-9}]))
    (_, first), (_, second) = list(s.runs())
    assert first == {"delta_m": 0.3, "h_ns": 0.65, "estimator": "paper", "seed": 0}
    spots = scene_of(s.plan(), second)["setup"]["detector_spots"]
    # bit-equal to how reproduce's loops built them: [-k * delta, 0.0, 0.0] and h * 1e-9
    assert spots == [[-k * 0.7, 0.0, 0.0] for k in (1, 2, 3)]
    assert assignments(s.plan(), first)["h_s"] == 0.65 * 1e-9
    assert load_study(s.as_dict()).fingerprint() == s.fingerprint()  # scale survives as_dict
    assert check_scenes(s) == 2


@pytest.mark.parametrize("name, runs, scenes", [
    ("fig7a", 10 * 2 * 3, 10), ("fig7b", 16 * 3, 1), ("table1", 6 * 3, 6), ("fig9", 9 * 2 * 3, 9),
    ("fig10", 25 * 3 * 3, 1 + 4 + 4)])  # scenes checked: each axis's values, others at first
def test_paper_study_files_load(name, runs, scenes):
    """The paper's sweeps as package study files: they load, have the classic loops' run
    counts, and every axis value gives a valid scene."""
    from importlib import resources
    path = resources.files("nlos_cl.sweep").joinpath(f"{name}.yaml")
    s = load_study(str(path))
    assert s.n_runs == runs and s.settings["grid"]["step_m"] == 0.01
    assert set(s.axes[-2].values) == {"paper"}  # the paper's figures: the paper's estimator
    assert check_scenes(s) == scenes
