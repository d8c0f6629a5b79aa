"""The type checker over the seams (scripts/typecheck.sh, pyproject's [tool.mypy]): the seam
modules pass, and it does check the Protocols: an estimator without `capabilities` and a motion
model without `process_noise` are refused where a Protocol type is asked for."""
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("mypy")
ROOT = Path(__file__).resolve().parents[2]


def _mypy(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mypy", "--no-incremental",
                           "--cache-dir", "/dev/null", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=600)


def test_the_seam_modules_type_check():
    run = _mypy()
    assert run.returncode == 0, run.stdout + run.stderr


def test_the_checker_refuses_what_breaks_a_protocol(tmp_path):
    bad = tmp_path / "bad_roles.py"
    bad.write_text(
        "import numpy as np\n"
        "from nlos_cl.localization.estimate import Estimator\n"
        "from nlos_cl.tracking.motion import MotionModel\n"
        "class NoCapabilities:\n"
        "    name = 'centroid'\n"
        "    def estimate(self, scored, prior=None): ...\n"
        "class NoNoise:\n"
        "    dims = None\n"
        "    initial_speed_sigma = 1.0\n"
        "    def transition(self, dt: float, d: int) -> np.ndarray: return np.eye(2 * d)\n"
        "estimator: Estimator = NoCapabilities()\n"
        "motion: MotionModel = NoNoise()\n")
    run = _mypy("--follow-imports=silent", "--ignore-missing-imports", str(bad))
    assert run.returncode == 1
    errors = [line for line in run.stdout.splitlines() if ": error:" in line]
    assert len(errors) == 2, run.stdout
    assert '"NoCapabilities", variable has type "Estimator"' in errors[0]
    assert '"NoNoise", variable has type "MotionModel"' in errors[1]
    assert "capabilities" in run.stdout and "process_noise" in run.stdout  # the missing members
