"""core.blas_threads: the model estimate's BLAS calls run on one thread and the library's
setting is restored after it; the user's own thread settings and the opt-out are left alone.
Each case in a fresh interpreter (BLAS keeps one setting per process)."""
import os
import subprocess
import sys

import pytest

pytest.importorskip("threadpoolctl")

# a paper-scene frame located by the model estimator, recording the BLAS threads the Poisson /
# Gauss linear solve (Problem.linear, the fit's innermost step) runs with
CHECK = """
import warnings
import nlos_cl as nl
from threadpoolctl import threadpool_info
from nlos_cl.localization.model.forward import likelihood

def blas_threads():
    return max([i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"] or [0])

seen, plain = [], likelihood.Problem.linear
def linear(self, cols, warm=None):
    if len(seen) < 3:
        seen.append(blas_threads())
    return plain(self, cols, warm)
likelihood.Problem.linear = linear

before = blas_threads()
scene = nl.paper_scene(position=(4.0, 2.0, 0.0))
noisy = nl.add_noise(nl.simulate(scene), snr_db=20, seed=0)
grid = nl.Grid.from_ranges(x=(0, 6), y=(0.01, 6), step_m=0.02)
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    nl.locate(nl.gauss_filter(noisy, h_s=0.65e-9), grid, raw=noisy)
print(before, max(seen), blas_threads())
"""


def _run(env_extra):
    env = {k: v for k, v in os.environ.items() if k not in
           ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "NLOS_CL_SERIAL_BLAS")}
    env.update(env_extra)
    out = subprocess.run([sys.executable, "-c", CHECK], env=env, capture_output=True,
                         text=True, check=True)
    return [int(v) for v in out.stdout.split()]


def test_one_thread_during_the_fit_and_restored_after():
    before, during, after = _run({})
    assert during == 1
    assert after == before


@pytest.mark.parametrize("env", [{"NLOS_CL_SERIAL_BLAS": "0"}, {"OMP_NUM_THREADS": "2"}])
def test_the_users_settings_and_the_opt_out_win(env):
    before, during, after = _run(env)
    assert during == before == after
    if "OMP_NUM_THREADS" in env:  # BLAS read it at start: two threads, kept through the fit
        assert during == 2
