"""`nlos-cl simulate --photons --tdc-ps T` with no --dt-ps simulates in bins that divide the TDC
bin (issue 55 item 5): a 33 ps TDC was refused ("not a whole number of the data's 1e-11 s
bins") though the user chose no simulation bin."""
import pytest

import nlos_cl as nl
from nlos_cl.apps import cli
from nlos_cl.core.paths import simulation_bin


@pytest.mark.parametrize("tdc_ps, dt_ps", [(50, 10), (33, 8.25), (7, 7), (1000, 10), (1333, 1333 / 134)])
def test_the_simulation_bin_divides_the_tdc_bin(tdc_ps, dt_ps):
    dt = simulation_bin(tdc_ps * 1e-12)
    assert dt == pytest.approx(dt_ps * 1e-12) and dt <= 10e-12 * (1 + 1e-9)
    assert (tdc_ps * 1e-12 / dt) == pytest.approx(round(tdc_ps * 1e-12 / dt))


def test_a_tdc_bin_of_33_ps_is_simulated_with_no_option(tmp_path):
    out = tmp_path / "c.h5"
    assert cli.main(["simulate", "--photons", "--tdc-ps", "33", "--out", str(out)]) == 0
    assert nl.read_capture(out)[0].time_axis.dt_s == pytest.approx(33e-12)


def test_a_scene_file_with_a_33_ps_tdc_and_no_bin_is_simulated(tmp_path):
    scene = tmp_path / "s.yaml"
    scene.write_text("targets: [{shape: rectangle, position: [4, 2, 0]}]\n"
                     "noise: {photons: {tdc_bin_s: 33.0e-12}}\n")
    out = tmp_path / "c.h5"
    assert cli.main(["simulate", str(scene), "--out", str(out)]) == 0
    assert nl.read_capture(out)[0].time_axis.dt_s == pytest.approx(33e-12)
