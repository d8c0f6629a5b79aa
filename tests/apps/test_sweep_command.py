"""`nlos-cl sweep`: the example study it prints loads, and its options are checked."""
import pytest

from nlos_cl.core.errors import InputError
from nlos_cl.sweep import load_study
from nlos_cl.sweep.study import check_scenes


def test_example_study_and_command(capsys):
    import yaml

    import nlos_cl as nl
    from nlos_cl.apps.sweep_cmd import _parser, main
    from nlos_cl.io.scenefile import yaml_loader
    assert main(_parser().parse_args(["--example"])) == 0
    text = capsys.readouterr().out
    s = load_study(yaml.load(text, Loader=yaml_loader()))
    assert s.n_runs == 108 and check_scenes(s) >= 1
    with pytest.raises(InputError, match="--out"):
        main(_parser().parse_args(["study.yaml"]))
    assert _parser().parse_args(["s.yaml", "--workers", "0"]).workers == 0  # in this process
    with pytest.raises(SystemExit):  # argparse: "--workers: must be an integer >= 0"
        _parser().parse_args(["s.yaml", "--workers", "-1"])
    capsys.readouterr()
    assert callable(nl.sweep) and callable(nl.sweep.read_table)
