"""The bench page's peer-tracker section (scripts/pf_peer.sh's JSON): its numbers as the script
measured them, and nothing where the script has not run or wrote something unreadable."""
import json

from nlos_cl.apps.bench.report import pf_peer_section


def _rows():
    return [{"tracker": "authors' PF (this run)", "frames": 475, "wall_s": 77.4, "loop_s": 21.0,
             "ids": "-", "to_shipped_pf_m": 0.082, "jitter_m": 0.0245},
            {"tracker": "nlos-cl track", "frames": 475, "wall_s": 20.5, "loop_s": 18.0,
             "ids": 1, "to_shipped_pf_m": 0.189, "jitter_m": 0.026}]


def test_the_section_reports_each_tracker_and_the_ratios(tmp_path):
    path = tmp_path / "pf.json"
    path.write_text(json.dumps({"date": "2026-12-03", "cpu": "a CPU", "threads": 2,
                                "frames": 475, "ratio_wall": 77.4 / 20.5,
                                "ratio_loop": 21.0 / 18.0, "rows": _rows()}))
    text = pf_peer_section(path)
    assert "| authors' PF (this run) | 475 | 77.4 | 6.1 | 21 | 22.6 | 0.082 | 0.0245 |" in text
    assert "| nlos-cl track | 475 | 20.5 | 23.2 | 18 | 26.4 | 0.189 | 0.0260 |" in text
    assert "**3.8x**" in text and "**1.2x**" in text and "a CPU" in text


def test_no_section_without_a_readable_file(tmp_path):
    assert pf_peer_section(tmp_path / "absent.json") == ""
    (tmp_path / "bad.json").write_text("{not json")
    assert pf_peer_section(tmp_path / "bad.json") == ""
    (tmp_path / "other.json").write_text(json.dumps({"frames": 3}))
    assert pf_peer_section(tmp_path / "other.json") == ""
