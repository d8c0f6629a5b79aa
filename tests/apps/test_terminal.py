"""A clean terminal (issue 24 item 7) and the red team that keeps it so (item 8): the CLI prints
each distinct warning once as one line `nlos-cl: warning: ...` with no source line; OpenCL
compiler output stays off the terminal unless --verbose (or inside the error of a failed build);
an unwritable cache folder falls back with one warning; a tight `ulimit -v` is refused in one
line; and tests/apps/redteam.py runs and classifies a few inputs."""
import os
import secrets
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import pytest

from nlos_cl.apps import calibrate as calibrate_cmd, cli
from nlos_cl.core.errors import DeviceError

REPO = Path(__file__).resolve().parents[2]
import redteam  # noqa: E402  (tests/apps/redteam.py, beside this file)
from redteam_cases import CASES, Case  # noqa: E402

WARNING_KERNEL = "__kernel void k(__global float *a) { int y = (int)a; a[0] = y; }\n"


def test_each_distinct_warning_is_one_line_once(monkeypatch, capsys, tmp_path):
    def noisy(args):
        for _ in range(3):
            warnings.warn("the same\n  thing, over two lines", RuntimeWarning)
        warnings.warn("another thing", UserWarning)
        return 0
    monkeypatch.setattr(calibrate_cmd, "calibrate", noisy)
    shown = warnings.showwarning
    assert cli.main(["calibrate", str(tmp_path / "pairs.csv")]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err == ["nlos-cl: warning: the same thing, over two lines",
                   "nlos-cl: warning: another thing"]
    assert warnings.showwarning is shown  # the library keeps Python's own format


def _cold_build(tmp_path, *flags):
    """`nlos-cl calibrate` made to build, on a cold kernel cache, a kernel the compiler warns
    about (as PoCL does on CPUs without AVX-512): stderr of the run."""
    code = textwrap.dedent(f"""
        import sys
        from nlos_cl.apps import calibrate as calibrate_cmd, cli
        from nlos_cl.device import runtime
        runtime.kernel_source = lambda name: "// {secrets.token_hex(8)}\\n" + {WARNING_KERNEL!r}
        calibrate_cmd.calibrate = lambda args: runtime.Runtime().kernel("w", "k") and 0
        sys.exit(cli.main(["calibrate", "pairs.csv", *{list(flags)!r}]))
        """)
    env = dict(os.environ, XDG_CACHE_HOME=str(tmp_path / f"cold{len(flags)}"))
    env.pop("NLOS_CL_VERBOSE", None)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, cwd=tmp_path, timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stderr


def test_compiler_output_only_with_verbose(tmp_path):
    """Each compiler words its warning its own way (PoCL's clang: "cast to smaller integer
    type"; NVIDIA's: a note on the kernel's inlining): the run is quiet without --verbose and
    shows the compiler's own lines under our header with it."""
    header = "OpenCL compiler output for kernels/w.cl"
    quiet = _cold_build(tmp_path)
    assert header not in quiet and "cast to smaller integer" not in quiet \
        and "generated" not in quiet, quiet
    loud = _cold_build(tmp_path, "--verbose")
    assert header in loud, loud
    said = loud.split(header, 1)[1].split("\n", 1)[1]  # the lines under the header
    assert said.strip(), loud
    assert "cast to smaller" in loud or "Portable Computing Language" not in loud


def test_a_failed_build_carries_the_compiler_output(runtime, capfd, monkeypatch):
    import pyopencl as cl
    from nlos_cl.device.runtime import build_program
    monkeypatch.delenv("NLOS_CL_VERBOSE", raising=False)
    # an undeclared name: an error for every compiler (a pointer cast to int, which PoCL
    # refuses, NVIDIA's compiler builds), and each names it in its message
    bad = cl.Program(runtime.context, f"// {secrets.token_hex(8)}\n"
                     + WARNING_KERNEL.replace("(int)a", "nlos_undeclared_name"))
    with pytest.raises(DeviceError, match="failed to build(.|\n)*nlos_undeclared_name"):
        build_program(bad, [], runtime.device, "kernels/bad.cl")
    assert "error" not in capfd.readouterr().err  # the compiler's own print was captured


def test_an_unwritable_cache_folder_falls_back_with_one_warning(monkeypatch, tmp_path):
    from nlos_cl.device import devices
    home = tmp_path / "home"
    home.write_text("a file, so no ~/.cache can be made")
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    with pytest.warns(RuntimeWarning, match="not writable.*Fix: set XDG_CACHE_HOME") as seen:
        devices._ensure_writable_cache()
    assert len(seen) == 1 and devices._writable(os.environ["XDG_CACHE_HOME"])


def test_a_tight_address_space_limit_is_refused_in_one_line(tmp_path):
    code = ("import resource, sys\nresource.setrlimit(resource.RLIMIT_AS, (600_000 * 1024,) * 2)"
            "\nfrom nlos_cl.apps import cli\nsys.exit(cli.main(['info']))")
    # One OpenBLAS thread: on a 16-core machine NumPy's import alone (16 threads' buffers)
    # outgrew the 600 MB before nlos_cl ran (pthread_create failed, exit -2), which no check of
    # ours can precede; the limit is meant for nlos_cl's OpenCL runtime.
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60, cwd=tmp_path, env=env)
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith("nlos-cl: ulimit -v: ") and done.stderr.count("\n") == 1
    assert "Fix: raise the limit" in done.stderr


def test_redteam_classifies():
    case = Case("vague", "x", lambda box: [])
    assert redteam.classify(case, 2, "", "nlos-cl: field: bad. Fix: do this", [], False) == "clear"
    assert redteam.classify(case, 2, "", "ValueError: cannot reshape", [], False) == "vague"
    assert redteam.classify(case, 1, "", "Traceback (most recent call last):\n", [], False) \
        == "traceback"
    assert redteam.classify(case, None, "", "", [], False) == "hang"
    assert redteam.classify(case, -9, "", "", [], False) == "memory"
    assert redteam.classify(case, 0, "", "", [], False) == "silently wrong"
    assert redteam.classify(case, 2, "", "nlos-cl: f: x. Fix: y", ["notes.md"], False) \
        == "data loss"
    assert redteam.classify(case, 2, "", "", [], True) == "security"


def test_redteam_runs_a_few_inputs(tmp_path):
    """Three inputs that need no fixture (each a second or so): the script end to end."""
    names = ["a folder named F.h5", "calibrate with a CSV of text", "a scene file that is a "
             "YAML list"]
    numbers = [str(i) for i, c in enumerate(CASES, 1) if c.name in names]
    assert len(numbers) == 3
    page = tmp_path / "redteam.md"
    done = subprocess.run([sys.executable, str(REPO / "tests" / "apps" / "redteam.py"),
                           *sum((["--case", n] for n in numbers), []), "--out", str(page)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    rows = [ln for ln in page.read_text().splitlines() if ln.startswith("| ") and
            ln.split("|")[1].strip().isdigit()]
    assert len(rows) == 3
    assert all(r.split("|")[4].strip() in redteam.OUTCOMES for r in rows)
    assert "summary:" in done.stdout and "(3 inputs)" in done.stdout


class _Terminal:
    def __init__(self, tty):
        self.tty, self.text = tty, []

    def isatty(self):
        return self.tty

    def write(self, s):
        self.text.append(s)

    def flush(self):
        pass


def test_long_work_shows_its_elapsed_seconds_on_a_terminal_only():
    """A long locate (a model fit on thousands of histograms: minutes) counts its seconds on
    a terminal's stderr and clears the line at the end; short work and pipes see nothing."""
    import time
    from nlos_cl.apps.terminal import Elapsed
    tty, pipe, quick = _Terminal(True), _Terminal(False), _Terminal(True)
    for stream in (tty, pipe):
        with Elapsed("locating (model estimator)", after_s=0.05, stream=stream):
            time.sleep(0.3)
    with Elapsed("locating", after_s=5.0, stream=quick):
        pass
    assert any(t.startswith("\rlocating (model estimator): ") and t.endswith(" s\033[K")
               for t in tty.text)  # no stage named: the seconds, the old line's rest cleared
    assert tty.text[-1] == "\r\033[K"
    assert pipe.text == [] and quick.text == []


def test_a_terminal_line_shows_the_librarys_stage():
    """core.progress's stage beside the seconds, the older line's rest cleared."""
    import time

    from nlos_cl.apps.terminal import Elapsed
    from nlos_cl.core import progress
    tty = _Terminal(True)
    try:
        with Elapsed("locating (model estimator)", after_s=0.05, stream=tty):
            progress.stage("model fit: closed shapes (boxes, ellipsoids, cylinders; 3 "
                           "histograms)")
            time.sleep(0.3)
    finally:
        progress.stage("")
    shown = [t for t in tty.text if "model fit: closed shapes" in t]
    assert shown and all(t.startswith("\rlocating (model estimator): ") for t in shown)
    assert shown[0].endswith("\033[K")
