"""Hostile command-line values (hypothesis): every numeric flag of every command, given
something it must refuse, exits with status 2 and one line on stderr naming the problem; never
a traceback, a hang or a written file. Run in-process (the CLI is a function) to stay fast."""
import contextlib
import io
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nlos_cl.apps.cli import main

# (command and fixed arguments, flag, how many values, whether 0 / negatives are refused)
FLAGS = [
    (["demo", "--png", ""], "--step", 1, "positive"),
    (["demo", "--png", ""], "--h-ns", 1, "positive"),
    (["demo", "--png", ""], "--seed", 1, "seed"),
    (["demo", "--png", ""], "--snr-db", 1, "finite"),
    (["demo", "--png", ""], "--position", 3, "finite"),
    (["simulate", "--out", "OUT"], "--facet", 1, "positive"),
    (["simulate", "--out", "OUT"], "--dt-ps", 1, "positive"),
    (["simulate", "--out", "OUT"], "--pulses", 1, "positive"),
    (["simulate", "--out", "OUT"], "--tdc-ps", 1, "positive"),
    (["simulate", "--out", "OUT"], "--seed", 1, "seed"),
    (["reproduce", "fig10"], "--seeds", 1, "seed1"),
    (["locate", "IN"], "--step", 1, "positive"),
    (["locate", "IN"], "--h-ns", 1, "positive"),
    (["locate", "IN"], "--region", 6, "finite"),
    (["track", "IN"], "--accel", 1, "positive"),
    (["track", "IN"], "--running-mean", 1, "positive"),
    (["track", "IN"], "--max-frames", 1, "seed1"),
    (["track", "IN"], "--region", 6, "finite"),
]
NOT_NUMBERS = st.sampled_from(["nan", "inf", "-inf", "1e999", "abc", "", "0x", "1,5", "--"])
REFUSED = {
    "positive": st.one_of(NOT_NUMBERS, st.sampled_from(["0", "-0", "-1", "-1e-300"])),
    "finite": NOT_NUMBERS,
    "seed": st.one_of(NOT_NUMBERS, st.sampled_from(["-1", "1.5", "1e3"])),
    "seed1": st.one_of(NOT_NUMBERS, st.sampled_from(["0", "-1", "2.5"])),
}


def run(argv):
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            status = main(argv)
        except SystemExit as exc:
            status = exc.code
    return status, err.getvalue()


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_a_refused_value_is_one_line_and_status_2(data, tmp_path_factory):
    base, flag, count, kind = data.draw(st.sampled_from(FLAGS))
    folder = tmp_path_factory.mktemp("cli")
    out, capture = folder / "out.h5", Path(__file__).parent / "data" / "missing.h5"
    argv = [str(out) if a == "OUT" else str(capture) if a == "IN" else a for a in base]
    bad = data.draw(REFUSED[kind])
    values = [bad] + ["1"] * (count - 1)
    values = data.draw(st.permutations(values))
    status, err = run(argv + [flag, *values])
    assert status == 2, (argv, flag, values, err)
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert not out.exists()  # nothing written


def test_unknown_flags_and_commands_are_one_line():
    for argv in (["frobnicate"], ["demo", "--no-such-flag"], [], ["locate"]):
        status, err = run(argv)
        assert status == 2 and len(err.strip().splitlines()) == 1, (argv, err)
