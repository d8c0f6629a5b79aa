"""core.allocator: glibc's thresholds set once, where they may be; the user's own settings and
the opt-out left alone (each in a fresh interpreter: the settings are per process)."""
import os
import subprocess
import sys

import pytest

CHECK = ("from nlos_cl.core import allocator; "
         "print(allocator.keep_freed_memory(), allocator.keep_freed_memory())")


def _run(env_extra):
    env = {k: v for k, v in os.environ.items()
           if k not in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "NLOS_CL_MALLOPT")}
    env.update(env_extra)
    out = subprocess.run([sys.executable, "-c", CHECK], env=env, capture_output=True,
                         text=True, check=True)
    return out.stdout.split()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_set_once_on_glibc_and_idempotent():
    import ctypes
    try:
        ctypes.CDLL(None).mallopt
    except AttributeError:
        pytest.skip("not glibc")
    assert _run({}) == ["True", "True"]


@pytest.mark.parametrize("env", [{"MALLOC_TRIM_THRESHOLD_": "131072"},
                                 {"MALLOC_MMAP_THRESHOLD_": "131072"},
                                 {"NLOS_CL_MALLOPT": "0"}])
def test_the_users_settings_and_the_opt_out_win(env):
    assert _run(env) == ["False", "False"]
