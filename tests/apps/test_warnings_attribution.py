"""What a user of the library sees of a warning (issue 56 item 5): the line of their own code
that called nlos_cl, never a library module's path, however deep the warning is raised."""
import subprocess
import sys

SCRIPT = """\
import warnings
warnings.simplefilter("always")
warnings.filterwarnings("error", category=RuntimeWarning)  # NumPy's floating-point warnings
import nlos_cl as nl
scene = nl.paper_scene(facet_size_m=0.05)
axis = nl.default_time_axis(scene.setup, 1e-11)
short = nl.TimeAxis(165.0e-9, axis.dt_s, 3000)  # detector 0's echo: 164.4-165.8 ns
signals = nl.simulate(scene, short)  # CALLER: the window cuts the echoes short
grid = nl.Grid.from_ranges(x=(3, 5), y=(1, 3), step_m=0.05)
nl.locate(nl.gauss_filter(nl.simulate(scene, axis)), grid, estimator="model")  # CALLER 2
"""


def test_warnings_point_at_the_callers_line(tmp_path):
    script = tmp_path / "user_script.py"
    script.write_text(SCRIPT)
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         timeout=600, check=False, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    warned = [ln for ln in out.stderr.splitlines() if "Warning: " in ln]
    lines = {n + 1 for n, ln in enumerate(SCRIPT.splitlines()) if "CALLER" in ln}
    assert any("cuts detector" in ln for ln in warned), out.stderr
    assert any("unobservable" in ln for ln in warned), out.stderr
    for ln in warned:
        where = ln.split(": ", 1)[0]
        assert where.rsplit(":", 1)[0] == str(script), ln  # never nlos_cl/...py
        assert int(where.rsplit(":", 1)[1]) in lines, ln
