"""The markdown of `reproduce tracking`: each section's table or list, formatted from its CSV
rows only, and the page it goes into. docs/tracking.md holds every section between markers
(<!-- reproduce tracking:NAME --> ... <!-- /reproduce tracking:NAME -->), so a run can replace
its sections there and leave the prose around them alone."""
from __future__ import annotations

import re
from pathlib import Path

from nlos_cl.core.errors import require

MARK = "reproduce tracking"


def path_table(first_column: str, lag: int, rows) -> str:
    """The lines and box table: per-frame, filter, fixed-lag and smoother errors, ratios, bound,
    goal; a case in which no frame had a track says so in every tracked column."""
    head = (f"| {first_column} | per-frame RMS / max (m) | filter RMS / max (m) | fixed lag "
            f"{lag} RMS / max (m) | smoother RMS / max (m) | ratio filter / lag / smoother | "
            "causal bound | goal met filter / lag / smoother |\n|---|---|---|---|---|---|---|---|")
    return "\n".join([head] + [_path_row(r) for r in rows])


def _pair(r, name) -> str:
    return f"{r[name + '_rms_m']:.4f} / {r[name + '_max_m']:.4f}"


def _path_row(r) -> str:
    raw = _pair(r, "per_frame")
    if r["frames_without_track"] == r["frames"]:
        return f"| {r['case']} | {raw} | no track | no track | no track | - | - | no / no / no |"
    columns = ("filter", "lag", "smoother")
    missing = (f" ({r['frames_without_track']} frames without a track)"
               if r["frames_without_track"] else "")
    ratios = " / ".join(f"{r['ratio_' + k]:.2f}" for k in columns)
    met = " / ".join("yes" if r["goal_" + k] else "no" for k in columns)
    return (f"| {r['case']} | {raw} | {_pair(r, 'filter')}{missing} | {_pair(r, 'lag')} | "
            f"{_pair(r, 'smoother')} | {ratios} | {r['causal_bound']:.2f} | {met} |")


def synthetic_table(rows) -> str:
    """One line per process noise, one column per path: filter RMS / per-frame RMS."""
    paths = list(dict.fromkeys(r["path"] for r in rows))
    lines = ["| accel_sigma | " + " | ".join(f"{p}: filter / per frame" for p in paths) + " |",
             "|---|" + "---|" * len(paths)]
    for accel in dict.fromkeys(r["accel_sigma"] for r in rows):
        cells = [f"{r['ratio']:.2f}" for r in rows if r["accel_sigma"] == accel]
        lines.append(f"| {accel} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def crossing_list(rows, spots: int, frames: int, check_frame: int) -> str:
    """Per seed whether the tracks kept their targets' identities, then the count and the time."""
    lines = [f"- seed {r['seed']}: track ids nearest the two targets at frame {check_frame} "
             f"{r['ids_start']}, at the end {r['ids_end']}: {'kept' if r['kept'] else 'LOST'}"
             for r in rows]
    kept, seconds = sum(r["kept"] for r in rows), sum(r["seconds"] for r in rows)
    return "\n".join(lines) + (
        f"\n\ncrossing ({spots} spots, model estimator, targets=2, {frames} frames): identities "
        f"kept in **{kept} of {len(rows)}** seeds ({seconds / len(rows) / frames:.2f} s/frame)")


def speed_table(rows) -> str:
    return "\n".join(["| estimator | frames | frames/s (host frames -> track states) |",
                      "|---|---|---|"] + [f"| {r['estimator']} | {r['frames']} | "
                                          f"{r['frames_per_s']:.1f} |" for r in rows])


def memory_list(rows) -> str:
    """What was written, then per max_history the peak RSS after each mark and the rate."""
    first = rows[0]
    lines = [f"memory: wrote {first['file_frames']} frames ({first['file_mib']:.0f} MiB) in "
             f"{first['write_s']:.1f} s"]
    for history in dict.fromkeys(r["max_history"] for r in rows):
        mine = [r for r in rows if r["max_history"] == history]
        marks = ", ".join(f"{r['after_frames']} frames: {r['peak_rss_mib']:.0f}" for r in mine)
        rate, cells = mine[0]["frames_per_s"], mine[0]["grid_cells"]
        lines.append(f"- max_history={history}: peak RSS (MiB) after {marks} "
                     f"({rate:.0f} frames/s on a {cells}^2 grid)")
    return "\n".join(lines)


def _marked(name: str, text: str) -> str:
    return f"<!-- {MARK}:{name} -->\n{text}\n<!-- /{MARK}:{name} -->"


def page(texts: dict, header: str) -> str:
    """A fresh page: the header, then every section between its markers."""
    return "\n\n".join([header] + [f"## {name}\n\n{_marked(name, text)}"
                                   for name, text in texts.items()]) + "\n"


def splice(path: Path, texts: dict) -> None:
    """Replace what `path` (docs/tracking.md) holds between each section's markers; a section
    without markers there is an error that says what to add (nothing is written then)."""
    doc = Path(path).read_text()
    for name, text in texts.items():
        pattern = re.compile(rf"<!-- {MARK}:{name} -->\n(?:.*?\n)?<!-- /{MARK}:{name} -->", re.S)
        require(bool(pattern.search(doc)), f"{path}", f"has no markers for section {name}",
                f"add <!-- {MARK}:{name} --> and <!-- /{MARK}:{name} --> where it should go")
        doc = pattern.sub(lambda _: _marked(name, text), doc)
    from ....io.safe_write import write_text
    # atomic, never through a link; the page is ours to edit: it holds our markers (above)
    write_text(path, doc, what="--doc", keep_unless=lambda _: True)
