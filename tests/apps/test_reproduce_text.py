"""What `nlos-cl reproduce` prints and the pages it writes read as tables for a researcher: an
aligned table per experiment (not a JSON dict), '-' where nothing was measured (not nan), no
issue numbers, no targets' checks (those are --json's), no row that repeats another."""
import math
import re
from argparse import Namespace
from pathlib import Path

from nlos_cl.apps.reproduce import common, report
from nlos_cl.apps.reproduce.beyond import report as beyond_report
from nlos_cl.apps.reproduce.draws import cross_report
from nlos_cl.apps.reproduce.draws import report as draws_report

BANNED = (r"\bnan\b", r"\bissue\b", r"NOT met", r"\bgoals?\b", r"[{}]")


def banned(text: str) -> list[str]:
    return [b for b in BANNED if re.search(b, text, re.IGNORECASE)]


def _fig6():
    rows = [{"method": m, "paper_x": 4.0, "paper_y": 2.0, "x": 4.02, "y": 2.01, "mean_m": e,
             "std_m": 0.001, "max_m": e} for m, e in (("filter", 0.0233), ("raw", 0.1063))]
    return common.Result("fig6", "Fig. 6: located position", rows, {"filter": rows[0]},
                         ["fig6.png"], 4.7)


def _checked():
    goals = [{"goal": "one target: default p90", "n": 200, "measured": "0.0392",
              "target": "<= 0.03 m", "met": False},
             {"goal": "crossings: tracking frames/s (median)", "n": 1, "measured": math.nan,
              "target": ">= 5", "met": False}]
    page = ("# Random draws\n\n| family | estimator | n | median (m) |\n|---|---|---|---|\n"
            "| one | default | 200 | 0.0026 |\n")
    return common.Result("draws", "Random draws", [], {"summary": [], "goals": goals,
                                                       "markdown": page}, [], 9.0)


def _columns(block: str) -> set[int]:
    """The starts of the columns of an aligned table (from its '---' line)."""
    rule = next(line for line in block.splitlines() if set(line.strip()) == {"-", " "})
    return {m.start() for m in re.finditer(r"-+", rule)}


def test_the_summary_is_an_aligned_table_per_experiment():
    text = report.summary_text([_fig6(), _checked()], Path("out"), 13.7)
    assert banned(text) == [], banned(text)
    fig6 = text.split("\n\n")[0]
    starts = _columns(fig6)
    for line in fig6.splitlines()[1:]:  # every row's cells start where the header's do
        for start in sorted(starts)[1:]:
            assert line[start - 2:start] == "  " and line[start] != " ", line
    assert "filter" in fig6 and "(4.0, 2.0)" in fig6 and "0.0233 ± 0.0010" in fig6
    # the targets' checks stay in --json: the terminal shows the page's first table
    draws = text.split("\n\n")[1]
    assert "one target: default p90" not in draws and "| family |" not in draws
    assert re.search(r"family\s+estimator\s+n\s+median", draws)


def test_the_command_prints_the_table_not_json(monkeypatch, tmp_path, capsys):
    from nlos_cl.apps import reproduce as rp
    from nlos_cl.apps import reproduce_cmd
    monkeypatch.setattr(rp, "run", lambda *a, **k: [_fig6()])
    args = Namespace(name="fig6", quick=True, seeds=None, out=str(tmp_path), doc=None,
                     force=False, only=None, cold=False, json=False)
    assert reproduce_cmd.main(args) == 0
    printed = capsys.readouterr().out
    assert banned(printed) == [], printed
    assert "fig6: Fig. 6: located position (4.7 s)" in printed and "wall time" in printed


def test_draws_pages_have_no_nan_and_no_repeated_rows():
    rows = [{"family": "closed", "sub": "box", "estimator": est, "layout": layout,
             "error_m": e * (2 if est == "paper" else 1), "k_found": 1, "k_true": 1, "seconds": 1.0, "warned": False,
             "depth_unseen": unseen}
            for est in ("paper", "default")
            for layout, e, unseen in (("circle", 0.01, False), ("random", 0.3, True),
                                      ("line-x", 0.02, False))]
    summ = draws_report.summary(rows, 0.15)
    lines = draws_report.summary_table(summ).splitlines()[2:]
    numbers = [line.split("|")[3:] for line in lines]  # estimator onwards
    assert len(numbers) == len({tuple(n) for n in numbers})  # no row repeats another
    assert {(r["sub"], r["estimator"]) for r in summ if r["sub"] == draws_report.TWO_SIDES} \
        == {(draws_report.TWO_SIDES, "default")}
    crossing = {"family": "crossings", "estimator": "default", "n": 1, "ids_kept": 0.0,
                "rms_median_m": math.inf, "rms_p90_m": math.inf, "rms_worst_m": math.inf,
                "rms_within_goal": 0.0, "fps_median": math.nan, "fps_spread": math.nan,
                "failed": 1}
    assert banned(cross_report.summary_table([crossing])) == []


def test_the_beyond_page_names_no_targets_nor_issues():
    """The page's prose and titles (the targets' checks are --json's only)."""
    prose = [v for k, v in beyond_report.TEXT.items() if isinstance(v, str)]
    prose += list(beyond_report.TEXT["titles"].values())
    words = [b for b in BANNED if b != r"[{}]"]  # templates hold their fields in braces
    assert [p for p in prose if any(re.search(b, p, re.IGNORECASE) for b in words)] == []
