import json
import subprocess
import sys


def run(*args):
    return subprocess.run([sys.executable, "-m", "nlos_cl.apps.cli", *args], capture_output=True,
                          text=True, timeout=600)


def test_info_self_check_passes():
    out = run("info")
    assert out.returncode == 0, out.stdout + out.stderr
    from nlos_cl.ops import OPERATIONS
    n_checks = sum(len(op.examples("check")) for op in OPERATIONS.values())
    assert n_checks >= 3 and out.stdout.count(" ok\n") == n_checks  # every operation checked
    # a bug report's versions, then one summary line
    lines = out.stdout.strip().splitlines()
    named = dict(ln.split(None, 1) for ln in lines if ln.startswith("  ") and len(ln.split()) > 1
                 and "self-check" not in ln)
    assert {"nlos_cl", "python", "numpy", "pyopencl", "platform", "driver", "device"} <= set(named)
    assert lines[-1] == f"summary: all {n_checks} self-checks passed on {named['device']}"


def test_version():
    import nlos_cl
    out = run("--version")
    assert out.returncode == 0 and out.stdout.strip() == f"nlos-cl {nlos_cl.__version__}"


def test_demo_json_locates_the_paper_target(tmp_path):
    png = tmp_path / "demo.png"
    out = run("demo", "--json", "--png", str(png))
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)
    assert result["error_m"] < 0.05
    assert result["truth"] == [4.0, 2.0, 0.0] and len(result["position"]) == 3
    assert result["device"]
    assert png.stat().st_size > 10_000


def test_demo_text_names_the_frame_of_its_positions():
    """The demo has no capture file: its positions are the paper's frame, said in the text as
    the JSON's "frame" says it (every output names its frame)."""
    out = run("demo", "--png", "")
    assert out.returncode == 0, out.stderr
    truth = next(line for line in out.stdout.splitlines() if line.startswith("truth"))
    assert "the paper's frame (x along the wall, y out from it, z up)" in truth


def test_bad_argument_is_a_clear_error():
    out = run("demo", "--json", "--h-ns", "-1", "--png", "")
    assert out.returncode == 2 and "h_s" in out.stderr and "Fix:" in out.stderr


def test_demo_track_json_tracks_the_walk():
    out = run("demo", "--track", "--estimator", "paper", "--json")
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)
    assert result["frames"] == 30 and result["tracked_rms_m"] < 0.10
    assert abs(result["final_position"][0] - result["final_truth"][0]) < 0.15
    # the demo's record holds its whole walk (4,096 bins cut the last frames' signal short)
    assert not [w for w in result["warnings"] if "cuts" in w], result["warnings"]


RETRO_SCENE = """\
setup:
  detector_spots: [[-0.5, 0, 0], [-1, 0, 0.5], [-1, 0, -0.5]]
targets:
  - shape: rectangle
    size_m: [0.3, 1.6]
    normal: [-1, 0, 0]
    position: [4, 2, 0]
    reflectance: {model: retroreflective, retro: 0.7, width_rad: 0.05, diffuse: 0.2}
facet_size_m: 0.02
time_axis: {dt_s: 10e-12}
noise: {snr_db: 20, seed: 1}
"""


def test_locate_and_track_take_the_targets_reflectance(tmp_path):
    """--reflectance: the model fit told the retroreflective lobe; a bad spec, or one given
    with the paper's argmax, is a one-line error."""
    scene = tmp_path / "retro.yaml"
    scene.write_text(RETRO_SCENE)
    capture = tmp_path / "retro.h5"
    out = run("simulate", str(scene), "--out", str(capture))
    assert out.returncode == 0, out.stderr
    lobe = "retroreflective:retro=0.7,width_rad=0.05,diffuse=0.2"
    errors = {}
    for label, extra in (("lambertian", []), ("lobe", ["--reflectance", lobe])):
        out = run("locate", str(capture), "--json", *extra)
        assert out.returncode == 0, out.stderr
        errors[label] = json.loads(out.stdout)["error_m"]  # against the truth the file holds
    # measured: 0.0025 m told the lobe, 1.0 m Lambertian (the paper's argmax: 0.86 m)
    assert errors["lobe"] < 0.02 and errors["lambertian"] > 0.1, errors
    for bad, field in ((["--reflectance", "retroreflective:retro=x"], "reflectance"),
                       (["--reflectance", "velvet"], "reflectance"),
                       (["--reflectance", lobe, "--estimator", "paper"], "--reflectance")):
        out = run("locate", str(capture), *bad)
        assert out.returncode == 2 and field in out.stderr and "Fix" in out.stderr, out.stderr
        assert len(out.stderr.strip().splitlines()) == 1


def test_the_quick_exit_keeps_every_output(tmp_path):
    """`nlos-cl` leaves with os._exit once main returns (console.run: no OpenCL and module
    teardown, ~30 ms of a one-shot locate): the JSON on stdout is whole, a file written is
    complete, atexit handlers still run, and the exit code is main's."""
    capture, figure, ran = tmp_path / "c.h5", tmp_path / "map.npz", tmp_path / "atexit-ran"
    assert run("simulate", "--out", str(capture), "--facet", "0.05").returncode == 0
    code = ("import atexit, pathlib, sys; "
            f"atexit.register(lambda: pathlib.Path({str(ran)!r}).write_text('ran')); "
            f"sys.argv = ['nlos-cl', 'locate', {str(capture)!r}, '--json', '--map', "
            f"{str(figure)!r}]; from nlos_cl.apps.console import run; run()")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr
    assert len(json.loads(out.stdout)["position"]) == 3
    import numpy as np
    with np.load(figure) as written:  # a whole zip: its directory is written last
        assert written["score"].size > 1000
    assert ran.read_text() == "ran"
    missing = run("locate", str(tmp_path / "none.h5"), "--json")
    assert missing.returncode == 2 and "does not exist" in missing.stderr


def test_a_reader_that_leaves_ends_the_command_quietly(tmp_path):
    """`nlos-cl locate F --json | head -c 0`: the pipe breaks; exit 1, no traceback and no
    'Exception ignored' (before: 'output: Broken pipe. Fix: pick a writable file path')."""
    capture = tmp_path / "c.h5"
    assert run("simulate", "--out", str(capture), "--facet", "0.05").returncode == 0
    proc = subprocess.Popen([sys.executable, "-m", "nlos_cl.apps.cli", "locate", str(capture),
                             "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # the reader leaves before the answer is written
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=600) == 1, err
    assert "Traceback" not in err and "Exception ignored" not in err and "Fix" not in err


def test_the_quick_exit_copes_with_closed_streams_and_prints_what_atexit_says(tmp_path):
    """Started with stdout closed (`>&-`): main's exit code, no traceback; what an atexit
    handler prints still reaches a piped stdout (the handlers run before the flush)."""
    code = ("import atexit, sys; atexit.register(lambda: print('from atexit')); "
            "sys.argv = ['nlos-cl', 'locate', 'none.h5']; from nlos_cl.apps.console import run; run()")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=600, cwd=tmp_path)
    assert out.returncode == 2 and "from atexit" in out.stdout, out.stderr
    closed = subprocess.run([sys.executable, "-c", code.replace("print('from atexit')",
                                                                "None")],
                            stdout=None, stderr=subprocess.PIPE, text=True, timeout=600,
                            cwd=tmp_path, stdin=subprocess.DEVNULL,
                            preexec_fn=lambda: __import__("os").close(1))
    assert closed.returncode == 2 and "Traceback" not in closed.stderr, closed.stderr
