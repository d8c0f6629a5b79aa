"""Reading is bounded and every value is checked where it enters (issue 24, items 3 and 6, and
item 7's corrupted-file messages): hostile YAML, values of the wrong kind or scale in scene and
study files, resumes over a damaged study folder, and HDF5 fields and failures each get one
line naming the field and the fix. Each case is a class of input, not one file."""
import json
import os
import subprocess
import sys
import textwrap
import time

import h5py
import numpy as np
import pytest
import yaml

import nlos_cl as nl
from error_catalogue import capture_file, histograms, replace_field
from nlos_cl.io.scenefile import load_scene, yaml_loader
from nlos_cl.io.ytal.reading import read_sequence
from nlos_cl.sweep import load_study, sweep
from nlos_cl.tracking import write_sequence

SCENE = "targets: [{shape: sphere, position: [4, 2, 0]}]\n"
SPHERE = {"shape": "sphere", "position": [4, 2, 0]}


def alias_bomb(levels=9, width=9) -> str:
    lines = [f"a0: &a0 [{', '.join(['x'] * width)}]"]
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * width)}]" for i in range(1, levels)]
    return "\n".join(lines) + f"\ndescription: *a{levels - 1}\n"


# ---------------------------------------------------------------- YAML, through one loader

@pytest.mark.parametrize("text, message", [
    (alias_bomb() + SCENE, "aliases expand to more than"),
    ("x: " + "[" * 20000 + "]" * 20000 + "\n" + SCENE, "more than 64 deep"),
    ("a: " + "{b: " * 100 + "1" + "}" * 100 + "\n" + SCENE, "more than 64 deep"),
    (SCENE + "targets: [{shape: box}]\n", "the key 'targets' appears twice"),
    ("setup: {device_distance_m: 20, device_distance_m: 30}\n" + SCENE, "appears twice"),
    ("description: &a [*a]\n" + SCENE, "inside its own anchor"),
])
def test_hostile_yaml_fails_fast_in_one_line(tmp_path, text, message):
    path = tmp_path / "scene.yaml"
    path.write_text(text)
    start = time.perf_counter()
    with pytest.raises(nl.InputError, match=message) as info:
        load_scene(path)
    assert time.perf_counter() - start < 5  # generous: a bomb's expansion would take minutes
    assert str(path) in str(info.value) and "Fix:" in str(info.value)
    assert len(str(info.value).splitlines()) == 1


def test_the_same_loader_guards_study_files_and_the_packaged_studies(tmp_path):
    path = tmp_path / "study.yaml"
    path.write_text(alias_bomb() + "scene: {targets: [{shape: sphere}]}\n")
    with pytest.raises(nl.InputError, match="study file .*aliases expand"):
        load_study(path)
    with pytest.raises(Exception, match="aliases expand"):  # apps/reproduce/paper/studies.py's use
        yaml.load(alias_bomb(), Loader=yaml_loader())
    assert yaml.load("dt: 1e-11\nt: 10e-12\n", Loader=yaml_loader()) == {"dt": 1e-11, "t": 1e-11}


def test_a_few_aliases_and_merge_keys_still_work(tmp_path):
    path = tmp_path / "scene.yaml"
    path.write_text("targets:\n  - &t {shape: sphere, position: [4, 2, 0]}\n"
                    "  - {<<: *t, position: [2, 4, 0]}\n")
    spec = load_scene(path)
    np.testing.assert_allclose(spec.scene.truths, [[4, 2, 0], [2, 4, 0]], atol=1e-9)


@pytest.mark.parametrize("encoding, message", [
    ("utf-16", "is UTF-16 text"), ("utf-16-le", "is UTF-16 or UTF-32 text"),
    ("utf-32", "is UTF-32 text"), ("latin-1", "is not UTF-8 text .*line 2"),
])
def test_text_that_is_not_utf8_is_named(tmp_path, encoding, message):
    path = tmp_path / "scene.yaml"
    path.write_bytes(("description: x\n" + "# caf\xe9\n" + SCENE).encode(encoding))
    with pytest.raises(nl.InputError, match=message + ".*Fix: save it as UTF-8"):
        load_scene(path)


def test_a_utf8_bom_is_fine(tmp_path):
    path = tmp_path / "scene.yaml"
    path.write_bytes(SCENE.encode("utf-8-sig"))
    assert load_scene(path).scene.truths.shape == (1, 3)


def test_a_folder_or_fifo_named_like_a_yaml_file_is_called_what_it_is(tmp_path):
    (tmp_path / "a.yaml").mkdir()
    os.mkfifo(tmp_path / "b.yaml")
    with pytest.raises(nl.InputError, match="is a folder, not a regular file"):
        load_scene(tmp_path / "a.yaml")
    with pytest.raises(nl.InputError, match="is a FIFO"):  # looked at, never opened
        load_study(tmp_path / "b.yaml")
    with pytest.raises(nl.InputError, match="does not exist"):
        load_scene(tmp_path / "c.yaml")


# ---------------------------------------------------------------- scene values

def scene(**top):
    return {"targets": [dict(SPHERE)], **top}


def target(**keys):
    return {"targets": [{**SPHERE, **keys}]}


@pytest.mark.parametrize("raw, field", [
    (scene(setup={"device_distance_m": 1e39}), "setup.device_distance_m"),
    (scene(setup={"device_distance_m": True}), "setup.device_distance_m"),
    (scene(setup={"wall_brdf": 0.5}), "setup.wall_brdf"),  # above a Lambertian's 1 / pi
    (scene(setup={"pulse": {"fwhm_s": 1e30}}), "setup.pulse.fwhm_s"),
    (scene(setup={"pulse": {"fwhm_s": "70e-12"}}), "setup.pulse.fwhm_s"),
    (scene(setup={"pulse": {"power_w": "x"}}), "setup.pulse.power_w"),
    (scene(setup={"pulse": {"energy_j": False}}), "setup.pulse.energy_j"),
    (scene(noise={"photons": {"n_pulses": 1e30}}), "noise.photons.n_pulses"),
    (scene(noise={"photons": {"efficiency": "high"}}), "noise.photons.efficiency"),
    (scene(noise={"snr_db": -1e300}), "noise.snr_db"),
    (scene(noise={"snr_db": True}), "noise.snr_db"),
    (scene(time_axis={"t0_s": 1e-7, "n_bins": 2.7}), "time_axis.n_bins"),
    (scene(time_axis={"t0_s": "soon", "n_bins": 100}), "time_axis.t0_s"),
    (scene(time_axis={"dt_s": 10}), "time_axis.dt_s"),  # 10 s bins: ps written as s?
    (scene(facet_size_m=True), "facet_size_m"),
    (scene(description=[1, 2]), "description"),
    (scene(setup={"detector_spots": {"spad_patch": {"centre": [-1, 0, 0],
                                                    "counts": [2.7, 2.7]}}}),
     "spad_patch.counts[0]"),
    (scene(setup={"detector_spots": {"spad_patch": {"centre": [-1, 0, 0],
                                                    "counts": ["a", "b"]}}}),
     "spad_patch.counts[0]"),
    (scene(setup={"detector_spots": {"spad_patch": {"centre": [-1, 0, 0],
                                                    "counts": [1000, 1000]}}}),
     "spad_patch.counts"),
    (scene(setup={"detector_spots": {"line": {"start": [-1, 0, 0], "stop": [-2, 0, 0],
                                              "count": 10 ** 9}}}), "line.count"),
    (scene(setup={"detector_spots": {"circle": {"centre": [-1, 0, 0], "radius_m": "big",
                                                "count": 4}}}), "circle.radius_m"),
    (scene(setup={"detector_spots": [[-500, 0, 0], [-1000, 0, 0]]}), "looks like millimetres"),
    (scene(setup={"laser_spot": [0, 0, True]}), "setup.laser_spot"),
    (target(position=[4000, 2000, 0]), "targets[0].position: .* looks like millimetres"),
    (target(position=[True, 2, 0]), "targets[0].position"),
    (target(position=["4", 2, 0]), "targets[0].position"),
    (target(radius_m=300), "targets[0].radius_m"),
    (target(scale=1e6), "targets[0].scale"),
    (target(scale=300), "targets[0]: spans .* millimetres"),  # a 0.4 m sphere x 300
    ({"targets": [{"shape": "sphere", "trajectory": {"t_s": ["a", "b"],
                                                     "positions": [[4, 2, 0], [4, 3, 0]]}}]},
     "trajectory.t_s"),
    ({"targets": [{"shape": "sphere", "trajectory": {"t_s": [False, True],
                                                     "positions": [[4, 2, 0], [4, 3, 0]]}}]},
     "trajectory.t_s"),
    ({"targets": [{"shape": "sphere", "trajectory": {"t_s": [0, 5],
                                                     "positions": [[4000, 2, 0], [4, 3, 0]]}}]},
     "trajectory.positions[0]"),
])
def test_scene_values_are_checked_where_they_enter(raw, field):
    before = json.dumps(raw)
    with pytest.raises(nl.InputError, match=field.replace("[", r"\[").replace("]", r"\]")
                       ) as info:
        load_scene(raw)
    assert "Fix:" in str(info.value)
    assert json.dumps(raw) == before  # nothing the user gave is modified


def test_the_documented_scenes_still_load():
    from pathlib import Path
    for path in sorted((Path(__file__).resolve().parents[2] / "docs" / "scenes").glob("*.yaml")):
        load_scene(path)


# ---------------------------------------------------------------- study values

BASE = {"targets": [dict(SPHERE)]}


@pytest.mark.parametrize("study, field", [
    ({"axes": [{"path": "noise.snr_db", "range": {"start": 0, "stop": float("inf"),
                                                   "step": 1}}]}, "axes[0].range.stop"),
    ({"axes": [{"path": "noise.snr_db", "range": {"start": "a", "stop": 5, "step": 1}}]},
     "axes[0].range.start"),
    ({"axes": [{"path": "noise.snr_db", "range": {"start": 0, "stop": 5, "step": True}}]},
     "axes[0].range.step"),
    ({"axes": [{"path": "noise.snr_db", "range": {"start": 0, "stop": 5, "num": 2.5}}]},
     "axes[0].range.num"),
    ({"axes": [{"path": "noise.snr_db", "range": {"start": 0, "stop": 1, "step": 1e-12}}]},
     "axes[0].range"),
    ({"axes": [{"path": "noise.snr_db", "name": "error_m", "values": [1]}]},
     "axes[0].name: 'error_m' is a column of the results table, reserved: .*'run_id'"),
    ({"axes": [{"path": "noise.snr_db", "name": "run_id", "values": [1]}]}, "axes[0].name"),
    ({"axes": [{"zip": [{"path": "noise.snr_db", "name": "failure", "values": [1]}]}]},
     "axes[0].zip[0].name"),
    ({"axes": [{"path": "noise.snr_db", "name": 5, "values": [1]}]}, "axes[0].name"),
    ({"h_s": True}, "h_s"), ({"h_s": float("inf")}, "h_s"),
    ({"batch_size": True}, "batch_size"), ({"batch_size": 2.5}, "batch_size"),
    ({"seeds": {"start": "a", "count": 2}}, "seeds.start"),
    ({"seeds": {"start": 1.5, "count": 2}}, "seeds.start"),
    ({"seeds": {"start": 0, "count": 2.7}}, "seeds.count"),
    ({"estimators": "paper"}, "estimators"),
])
def test_study_values_are_checked_where_they_enter(study, field):
    raw = {"scene": BASE, **study}
    before = json.dumps(raw)
    with pytest.raises(nl.InputError, match=field.replace("[", r"\[").replace("]", r"\]")):
        load_study(raw)
    assert json.dumps(raw) == before


# ---------------------------------------------------------------- --resume over a damaged folder

@pytest.fixture
def runner_study(tmp_path, monkeypatch):
    (tmp_path / "my_quick_runs.py").write_text(textwrap.dedent("""
        def run(n, seed=0):
            return {"n2": n * n}
    """))
    monkeypatch.syspath_prepend(str(tmp_path))
    study = {"runner": "my_quick_runs:run", "axes": [{"name": "n", "values": [1, 2, 3, 4]}],
             "batch_size": 1}
    out = tmp_path / "out"
    sweep(study, out, workers=0, progress=False, report=False, allow_runner=["my_quick_runs"])
    return study, out


def resume(study, out):
    return sweep(study, out, workers=0, progress=False, report=False, resume=True,
                 allow_runner=["my_quick_runs"])


def parts(out):
    return sorted((out / "runs.parquet").glob("part-*.parquet"))


def test_a_resume_checks_the_record_and_every_part(runner_study):
    study, out = runner_study
    assert resume(study, out).n_skipped == 4  # an intact folder resumes
    (out / "study.json").write_text('{"fingerprint": ')
    with pytest.raises(nl.InputError, match="study.json is not readable JSON"):
        resume(study, out)
    (out / "study.json").unlink()
    with pytest.raises(nl.InputError, match="but no study.json, so which study"):
        resume(study, out)


@pytest.mark.parametrize("damage, message", [
    (lambda out: parts(out)[0].write_bytes(parts(out)[0].read_bytes()[:-40]),
     "is truncated or corrupted .*Fix: delete that part"),
    (lambda out: (out / "runs.parquet" / "notes.txt").write_text("mine"),
     "notes.txt is not a part nlos_cl wrote"),
    (lambda out: (out / "runs.parquet" / "part-000000009-0123abcd.parquet").write_bytes(b"x"),
     "is truncated or corrupted"),
])
def test_a_damaged_table_is_named_not_read_past(runner_study, damage, message):
    study, out = runner_study
    damage(out)
    with pytest.raises(nl.InputError, match=message):
        resume(study, out)


def test_another_studys_part_is_not_mixed_in(runner_study, tmp_path):
    study, out = runner_study
    other = {**study, "axes": [{"name": "n", "values": [7, 8, 9, 10]}]}
    sweep(other, tmp_path / "other", workers=0, progress=False, report=False,
          allow_runner=["my_quick_runs"])
    parts(out)[0].unlink()
    stray = parts(tmp_path / "other")[1]
    (out / "runs.parquet" / stray.name).write_bytes(stray.read_bytes())
    with pytest.raises(nl.InputError, match="axis values differ from this study's"):
        resume(study, out)


# ---------------------------------------------------------------- HDF5 fields

FLAG = "t_accounts_first_and_last_bounces"


@pytest.mark.parametrize("stored, legs", [
    ("False", False), ("false", False), (b"FALSE", False), ("0", False), (0, False),
    ("True", True), ("TRUE", True), (b"true", True), ("1", True), (np.bool_(True), True),
])
def test_booleans_stored_as_text_read_as_what_they_say(stored, legs):
    plain = nl.read_capture(capture_file(replace_field(FLAG, legs)))[0]
    text = nl.read_capture(capture_file(replace_field(FLAG, stored)))[0]
    np.testing.assert_array_equal(text.calibration.b_m, plain.calibration.b_m)


@pytest.mark.parametrize("stored", ["maybe", "yes", 2, 0.5, ""])
def test_other_booleans_are_refused(stored):
    with pytest.raises(nl.InputError, match=f"{FLAG}: expected a boolean"):
        nl.read_capture(capture_file(replace_field(FLAG, stored)))


def _scene_info(edit):
    def change(f):
        info = yaml.safe_load(f["scene_info"][()])
        edit(info["nlos_cl"])
        del f["scene_info"]
        f["scene_info"] = yaml.safe_dump(info)
    return change


@pytest.mark.parametrize("edit, message", [
    (lambda f: (replace_field("laser_xyz", np.zeros((2, 3), np.float32))(f),
                replace_field(FLAG, True)(f)), "laser_xyz: has shape \\(2, 3\\)"),
    (lambda f: (f.__delitem__("H"), f.create_group("H")), "H: is a group, not a dataset"),
    (lambda f: f["sensor_grid_xyz"].__setitem__(slice(None), f["sensor_grid_xyz"][()] * 1e3),
     "sensor_grid_xyz: its points span 1000 m .*millimetres"),
    (lambda f: f["delta_t"].__setitem__((), f["delta_t"][()] * 1e3),
     "delta_t: is 2.998 m .*millimetres"),
    (lambda f: (f.__delitem__("scene_info"), f.__setitem__("scene_info", alias_bomb())),
     "scene_info: its aliases expand"),
    (_scene_info(lambda ours: ours.__setitem__("truth", "here")), "nlos_cl.truth"),
    (_scene_info(lambda ours: ours.__setitem__("allow_negative", "perhaps")),
     "allow_negative: expected a boolean"),
])
def test_capture_fields_are_checked_where_they_enter(edit, message):
    with pytest.raises(nl.InputError, match=message):
        nl.read_capture(capture_file(edit))


def test_text_false_in_our_metadata_is_false():
    h = nl.read_capture(capture_file(_scene_info(lambda o: o.__setitem__("allow_negative",
                                                                          "False"))))[0]
    assert h.allow_negative is False


def test_a_capture_with_a_user_block_is_read(tmp_path):
    source, path = capture_file(), tmp_path / "ub.h5"
    with h5py.File(source, "r") as a, h5py.File(path, "w", userblock_size=512) as b:
        for key in a:
            a.copy(a[key], b, name=key)
    np.testing.assert_array_equal(nl.read_capture(path)[0].data, nl.read_capture(source)[0].data)
    path.write_bytes(path.read_bytes()[:-100])  # and a cut-off one is still caught
    with pytest.raises(nl.InputError, match="incomplete or corrupted"):
        nl.read_capture(path)


def _mat73(path, variables):
    """A MATLAB v7.3 file as MATLAB writes one: a 512-byte header, then HDF5; h5py stores
    MATLAB's arrays with their axes reversed."""
    with h5py.File(path, "w", userblock_size=512) as f:
        for name, value in variables.items():
            f[name] = np.asarray(value, np.float64).T
            f[name].attrs["MATLAB_class"] = np.bytes_(b"double")
    with open(path, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".ljust(116)
                 + bytes(8) + b"\x00\x02IM")
    return path


def test_a_matlab_v73_file_is_named_and_lct_reads_it(tmp_path):
    import scipy.io
    cube = np.random.default_rng(1).poisson(3.0, (4, 5, 60)).astype(np.float64)
    v5, v73 = tmp_path / "v5.mat", tmp_path / "v73.mat"
    scipy.io.savemat(v5, {"rect_data": cube, "width": np.array([[0.35]])})
    _mat73(v73, {"rect_data": cube, "width": [[0.35]]})
    with pytest.raises(nl.InputError, match="is a MATLAB .mat file .*HDF5 inside.*nlos-cl "
                                            "convert"):
        nl.read_capture(v73)
    a, b = nl.read_dataset(v5), nl.read_dataset(v73)  # detected as lct either way
    np.testing.assert_array_equal(a.data, b.data)
    np.testing.assert_array_equal(a.detector_spots, b.detector_spots)


def test_a_capture_locked_by_its_writer_says_so(tmp_path):
    path = capture_file()
    code = f"import h5py, time\nf = h5py.File({str(path)!r}, 'a')\nprint('open', flush=True)\n" \
           "time.sleep(60)"
    writer = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert writer.stdout.readline().strip() == "open"
        with pytest.raises(nl.InputError, match="is locked: another program has it open"):
            nl.read_capture(path)
    finally:
        writer.kill()
        writer.wait()


def test_a_missing_compression_filter_is_named(tmp_path):
    path = capture_file(lambda f: (f.__setitem__("H2", f["H"][()]), f.__delitem__("H"),
                                   f.create_dataset("H", data=f["H2"][()], compression="lzf"),
                                   f.__delitem__("H2")))
    code = ("import h5py, nlos_cl as nl\nh5py.h5z.unregister_filter(h5py.h5z.FILTER_LZF)\n"
            f"try:\n    nl.read_capture({str(path)!r})\nexcept nl.InputError as e:\n    print(e)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert "H: is compressed with an HDF5 filter this h5py does not have" in done.stdout, \
        done.stdout + done.stderr
    assert "(lzf)" in done.stdout and "pip install hdf5plugin" in done.stdout


# ---------------------------------------------------------------- sequences

def sequence(tmp_path, edit=None, n=3):
    frames = [(k * 0.1, histograms(np.ones((3, 100)) * (k + 1)), np.array([[4.0, 2.0, 0.0]]))
              for k in range(n)]
    path = write_sequence(tmp_path / "seq.h5", frames)
    if edit:
        with h5py.File(path, "a") as f:
            edit(f)
    return path


@pytest.mark.parametrize("edit, message", [
    (replace_field("frame_truths", np.zeros((2, 1, 3))), "frame_truths: is float64 \\(2, 1, 3\\)"),
    (replace_field("frame_truths", np.zeros((3, 1, 2))), "frame_truths: .*expected numbers"),
    (replace_field("frame_truths", np.array([b"a", b"b", b"c"])), "frame_truths"),
    (lambda f: (f.__delitem__("frame_truths"), f.create_group("frame_truths")), "frame_truths"),
    (replace_field("frame_t_s", np.array([0.0, 100.0, 200.0])),
     "frame_t_s: frames are 100 s apart .*looks like milliseconds .*divide by 1000"),
    (replace_field("frame_t_s", np.array([0.0, 1e5, 2e5])), "looks like microseconds"),
    (replace_field("frame_t_s", np.array([0.0, -0.1, -0.2])), "must increase strictly"),
    (replace_field("frame_t_s", np.array([0.0, np.nan, 0.2])), "frame_t_s: contains NaN"),
    (replace_field("frame_t_s", np.array([b"a", b"b", b"c"])), "frame_t_s: is |S1, not numbers"),
    (replace_field("frame_t_s", np.array([0.0, 0.1])), "frame_t_s: has 2 entries for 3"),
    (lambda f: (f.__delitem__("frame_t_s"), f.create_group("frame_t_s")), "frame_t_s: is a group"),
])
def test_sequence_fields_are_checked_when_it_is_opened(tmp_path, edit, message):
    with pytest.raises(nl.InputError, match=message):
        read_sequence(sequence(tmp_path, edit))


def test_a_sequence_path_that_is_a_folder_or_fifo_is_called_so(tmp_path):
    (tmp_path / "F.h5").mkdir()
    os.mkfifo(tmp_path / "G.h5")
    with pytest.raises(nl.InputError, match="sequence .*F.h5: is a folder"):
        read_sequence(tmp_path / "F.h5")
    with pytest.raises(nl.InputError, match="sequence .*G.h5: is a FIFO"):
        read_sequence(tmp_path / "G.h5")


def test_a_one_frame_sequence_checks_its_metadata(tmp_path):
    def edit(f):
        info = yaml.safe_load(f["scene_info"][()])
        info["nlos_cl"]["metadata"] = {"sequence": {"t_s": ["noon"]}}
        del f["scene_info"]
        f["scene_info"] = yaml.safe_dump(info)
    with pytest.raises(nl.InputError, match="scene_info sequence.t_s"):
        read_sequence(capture_file(edit))


def test_the_writer_refuses_what_the_reader_would(tmp_path):
    frames = [(k * 100.0, histograms()) for k in range(3)]  # milliseconds passed as seconds
    with pytest.raises(nl.InputError, match="frames.t_s: .*looks like milliseconds"):
        write_sequence(tmp_path / "ms.h5", frames)
    assert not (tmp_path / "ms.h5").exists()
    assert len(list(read_sequence(sequence(tmp_path)))) == 3  # 10 fps is a frame rate
