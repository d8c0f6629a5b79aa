"""`nlos-cl simulate --photons --tdc-ps T` with no --dt-ps simulates in bins that divide the TDC
bin (issue 55 item 5): a 33 ps TDC was refused ("not a whole number of the data's 1e-11 s
bins") though the user chose no simulation bin. And the paper scene's --position is in the
capture's (y-tal's) frame, as every output (issue 56 item 1)."""
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


def test_the_paper_scenes_position_is_given_in_the_captures_frame(tmp_path, capsys):
    """`--position X Y Z` is y-tal's X, Y, Z, as the capture and every command reading it give
    them (the internal frame stays in the library): the truth written is where the user put
    it, the message says so, and the default is the paper's target there."""
    from nlos_cl.io.ytal.capture import read_capture_with_frame
    out = tmp_path / "c.h5"
    argv = ["simulate", "--facet", "0.05", "--out", str(out), "--force"]
    assert cli.main(argv + ["--position", "-3", "0.5", "1.5"]) == 0
    assert "(X, Y, Z) = [[-3.0, 0.5, 1.5]] m in the capture's y-tal frame" in capsys.readouterr().out
    sets, frame = read_capture_with_frame(out)
    assert frame.from_internal(sets[0].truth) == pytest.approx([-3.0, 0.5, 1.5])
    assert cli.main(argv) == 0
    assert "(X, Y, Z) = [[-4.0, 0.0, 2.0]] m" in capsys.readouterr().out


@pytest.mark.parametrize("position, said", [(["4", "2", "0"], "Z = 0 m"),
                                            (["-4000", "0", "2000"], "millimetres")])
def test_a_position_outside_the_hidden_space_is_refused_in_the_captures_frame(tmp_path, capsys,
                                                                             position, said):
    assert cli.main(["simulate", "--out", str(tmp_path / "c.h5"), "--position", *position]) != 0
    err = capsys.readouterr().err
    assert "--position: " in err and said in err and "Fix: " in err and "y = " not in err


def test_simulate_help_states_the_captures_frame(capsys):
    with pytest.raises(SystemExit):
        cli.main(["simulate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "y-tal's frame" in text and "default -4 0 2" in text and "nlos_cl's frame" not in text
