"""The README as a first-time reader meets it: each section that has commands shows them in a
code block right under its heading (its first screen), every `nlos-cl` command is shown in one
such block, and every script a section names is in its own block, not only in its prose."""
import re
from pathlib import Path

from nlos_cl.apps.cli import COMMANDS

README = Path(__file__).resolve().parents[2] / "README.md"
FIRST_LINES = 3  # a section's code block starts right under its heading


def sections() -> list[tuple[str, list[str]]]:
    """(heading, the lines under it) per heading of README.md."""
    out, fenced = [], False
    for line in README.read_text().splitlines():
        fenced ^= line.startswith("```")
        if line.startswith("#") and not fenced:  # a comment in a code block is no heading
            out.append((line, []))
        elif out:
            out[-1][1].append(line)
    return out


def first_block(body: list[str]) -> tuple[int, str]:
    """(the line where the section's first code block starts, its text) or (-1, '')."""
    fences = [i for i, line in enumerate(body) if line.startswith("```")]
    if len(fences) < 2:
        return -1, ""
    return fences[0], "\n".join(body[fences[0] + 1:fences[1]])


def test_each_section_shows_its_commands_first():
    for heading, body in sections():
        start, block = first_block(body)
        scripts = set(re.findall(r"scripts/\w+\.sh", "\n".join(body)))
        if not scripts and "nlos-cl " not in block:
            continue  # no command of its own (conventions, layout)
        assert 0 <= start < FIRST_LINES, f"{heading}: its commands start at line {start}"
        missing = sorted(s for s in scripts if s not in block)
        assert not missing, f"{heading}: {missing} named in its prose, not in its code block"


def test_every_command_is_shown_in_a_code_block():
    blocks = "\n".join(re.findall(r"^```\w*\n(.*?)^```", README.read_text(),
                                  re.MULTILINE | re.DOTALL))
    shown = set(re.findall(r"^nlos-cl ([a-z]+)", blocks, re.MULTILINE))
    assert set(COMMANDS) <= shown, sorted(set(COMMANDS) - shown)


def test_the_python_api_block_runs_without_warning_text(capsys):
    """The README's first Python block, run as a reader pastes it: no Python warning (the
    paper's collinear spots gave 'height (up the wall) is unobservable' as a UserWarning)."""
    import warnings
    [code] = re.findall(r"^```python\n(.*?)^```", README.read_text(), re.MULTILINE | re.DOTALL)[:1]
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        exec(compile(code, "README.md", "exec"), {})  # noqa: S102 - the README's own code
    assert [str(w.message) for w in said] == []
    assert "[4.0" in capsys.readouterr().out  # it printed the located position
