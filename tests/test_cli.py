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


def test_demo_json_locates_the_paper_target(tmp_path):
    png = tmp_path / "demo.png"
    out = run("demo", "--json", "--png", str(png))
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)
    assert result["error_m"] < 0.05
    assert result["truth"] == [4.0, 2.0, 0.0] and len(result["position"]) == 3
    assert result["device"]
    assert png.stat().st_size > 10_000


def test_bad_argument_is_a_clear_error():
    out = run("demo", "--json", "--h-ns", "-1", "--png", "")
    assert out.returncode == 2 and "h_s" in out.stderr and "Fix:" in out.stderr


def test_demo_track_json_tracks_the_walk():
    out = run("demo", "--track", "--estimator", "paper", "--json")
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)
    assert result["frames"] == 30 and result["tracked_rms_m"] < 0.10
    assert abs(result["final_position"][0] - result["final_truth"][0]) < 0.15
