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


def _sweep(*args):
    """`nlos-cl sweep ARGS` in this process: (status, stderr)."""
    import contextlib
    import io

    from nlos_cl.apps.cli import main
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        status = main(["sweep", *map(str, args), "--workers", "0", "--no-progress"])
    return status, err.getvalue().strip()


INNER = "runner: \"subprocess:getoutput\"\naxes: [{name: cmd, values: [\"touch OWNED\"]}]\n"


@pytest.mark.parametrize("study", [
    # the engine itself, running an inner study that names a shell command
    ("runner: nlos_cl.sweep.engine:sweep\naxes: [{name: study, values: [inner.yaml]}]\n"
     "params: {out: o2, allow_runner: [subprocess]}\n"),
    ("runner: nlos_cl.apps.cli:main\naxes: [{name: argv, values: [[sweep, inner.yaml, --out, "
     "o3, --workers, '0', --allow-runner, subprocess]]}]\n"),
    ("runner: nlos_cl.io.safe_write:write_text\naxes: [{name: path, values: [precious.txt]}]\n"
     "params: {text: gone, what: x, force: true}\n"),
    "runner: nlos_cl:sweep\naxes: [{name: study, values: [inner.yaml]}]\n",
])
def test_a_study_cannot_reach_nlos_cl_s_unregistered_functions(tmp_path, monkeypatch, study):
    """The red team's three security findings, by the command: exit 2, one line, and no
    command ran and no file changed."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "inner.yaml").write_text(INNER)
    (tmp_path / "precious.txt").write_text("mine\n")
    (tmp_path / "s.yaml").write_text(study)
    for allow in ([], ["--allow-runner", "nlos_cl"]):
        status, err = _sweep("s.yaml", "--out", "out", *allow)
        assert status == 2 and len(err.splitlines()) == 1 and err.startswith("nlos-cl: runner '")
        assert "Fix:" in err
    assert not (tmp_path / "OWNED").exists()
    assert (tmp_path / "precious.txt").read_text() == "mine\n"


def test_a_study_naming_a_system_file_as_its_scene_does_not_print_it(tmp_path):
    status, err = _sweep(_write(tmp_path, "scene: /etc/passwd\n"), "--out", tmp_path / "o")
    assert status == 2 and len(err.splitlines()) == 1 and "root:" not in err


def _write(folder, text):
    (folder / "s.yaml").write_text(text)
    return folder / "s.yaml"
