"""What `nlos-cl bench` prints and writes reads as a table for a researcher: no NaN where a row
has no twin or no probe, no issue numbers, no check against a target (those go in the note)."""
import math
import re

from nlos_cl.apps.bench import Row
from nlos_cl.apps.bench.report import table

USER_TEXT_BANS = (r"\bnan\b", r"\bissue\b", r"NOT met", r"\bgoal\b", r"\btarget [<>]=",
                  r": (yes|no) \|")  # a target's check belongs in the note, not the table


def banned(text: str) -> list[str]:
    return [b for b in USER_TEXT_BANS if re.search(b, text, re.IGNORECASE)]


def test_a_row_without_twin_or_memory_prints_dashes():
    row = Row("stream", "a case", 1, 0.01, math.nan, 0.0, 100.0, "frames", math.nan, "-",
              math.nan, 0.1, note="per frame")
    line = table([row]).splitlines()[-1]
    assert banned(line) == []
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert cells[4:6] == ["-", "-"] and cells[10] == "-"  # twin, ratio, peak host MiB


def test_the_smoke_bench_prints_no_nan_nor_issue_numbers():
    """Every row of a smoke bench (seconds): measurements only, no check against a target; and
    no warning on the terminal (the model rows' scene holds its height: a note about the
    bench's own scene, which it printed between the progress lines)."""
    import warnings

    from nlos_cl.apps.bench import run
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        text = run(smoke=True, say=lambda _: None)
    assert banned(text) == [], banned(text)
    assert [str(w.message) for w in said] == []
    for line in text.splitlines():  # a note names a twin only where the row has one
        cells = [c.strip() for c in line.strip("|").split("|")]
        if len(cells) > 12 and "twin: one frame" in cells[12]:
            assert cells[4] != "-", line
