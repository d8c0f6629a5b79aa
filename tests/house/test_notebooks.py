"""Every notebook in notebooks/ runs top to bottom (outputs are not kept in git), says nothing a
reader should not see (no warning text, no issue numbers: what it prints is printed by its
cells, not Python's warning machinery) and writes nothing where it runs (its own folder, for a
reader: a temporary folder only)."""
import re
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOKS = sorted((Path(__file__).resolve().parents[2] / "notebooks").glob("*.ipynb"))
# UserWarning, RuntimeWarning, "WARNING |" log lines...; "issue 21", "Issue #56"
UNWANTED = re.compile(r"warning|\bissue\s*#?\d+", re.IGNORECASE)


def _run(path, folder, monkeypatch, **env):
    nb = nbformat.read(path, as_version=4)
    assert all(not cell.get("outputs") for cell in nb.cells if cell.cell_type == "code"), \
        "clear the notebook's outputs before committing"
    monkeypatch.setenv("NLOS_CL_QUICK", "1")  # the kernel inherits it: the coarse setting
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    NotebookClient(nb, timeout=300, kernel_name="python3",
                   resources={"metadata": {"path": str(folder)}}).execute()
    return nb


def _texts(nb):
    """(cell index, text) of every output: streams (stdout and stderr) and plain-text results."""
    for i, cell in enumerate(nb.cells):
        for out in cell.get("outputs", []) if cell.cell_type == "code" else []:
            if out.output_type == "stream":
                yield i, out.text
            elif "text/plain" in out.get("data", {}):
                yield i, out.data["text/plain"]


def unwanted(nb) -> list[str]:
    """Each output line with warning text or an issue number, with its cell's index."""
    return [f"cell {i}: {line.strip()}" for i, text in _texts(nb)
            for line in text.splitlines() if UNWANTED.search(line)]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_runs(path, tmp_path, monkeypatch):
    nb = _run(path, tmp_path, monkeypatch)
    assert not unwanted(nb), "\n".join(unwanted(nb))
    written = sorted(p.name for p in tmp_path.iterdir())
    assert not written, f"{path.name} wrote {written} where it runs: write to a temporary folder"


def test_measured_data_says_when_the_data_are_absent(tmp_path, monkeypatch):
    """Without ../shared/realdata the measured-data notebook prints one line and runs on."""
    path = next(p for p in NOTEBOOKS if p.name == "measured_data.ipynb")
    nb = _run(path, tmp_path, monkeypatch, NLOS_CL_REALDATA=str(tmp_path / "absent"))
    said = [text for _, text in _texts(nb)]
    assert len(said) == 1 and said[0].startswith("skipped:") and "NLOS_CL_REALDATA" in said[0]


def test_unwanted_text_is_found():
    """The check itself: a warning's text, a log line and an issue number are caught; plain
    prose is not."""
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell()])
    outputs = nb.cells[0].outputs
    for text in ("located [4. 2. 0.]\n", "x.py:2: UserWarning: height (z) is unobservable\n",
                 "RuntimeWarning: invalid value\n", "see issue 21\n", "Issue #56 fixed\n",
                 "[IPKernelApp] WARNING | Kernel\n"):
        outputs.append(nbformat.v4.new_output("stream", name="stderr", text=text))
    assert len(unwanted(nb)) == 5
