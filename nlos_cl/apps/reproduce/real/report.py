"""docs/results/real-data/real-data.md from a `reproduce real` run: per dataset its geometry
(real.yaml, from the dataset's README), what nlos_cl found, the truth it ships, the error and the
time; the Keyhole and walk figures; the goals met or not with the number (`goals`: for
--json, not the page)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...plotting import pyplot, save

SECTION_TITLES = {"ccsocr": "CC-SOCR figure 4 (paired: one detection point, a scanned laser)",
                  "lct": "LCT confocal scans", "keyhole": "Keyhole E, K, Y (one confocal spot)",
                  "walk": "consumer-nlos walk (4 x 4 zones, a person walking)"}


def figures(sections: dict, out: Path) -> list[str]:
    """real-keyhole.png (range over time, each letter) and real-walk.png (top view)."""
    names = []
    if sections.get("keyhole"):
        names.append(_keyhole_figure(sections["keyhole"]["series"], out))
    if sections.get("walk"):
        names.append(_walk_figure(sections["walk"]["series"], out))
    return names


def _keyhole_figure(series, out) -> str:
    plt = pyplot()
    fig, axes = plt.subplots(1, len(series), figsize=(4 * len(series), 3), squeeze=False,
                             layout="constrained")
    for ax, (letter, (ours, stage, offset)) in zip(axes[0], series.items()):
        ax.plot(stage, "k-", lw=1.5, label="from the stage")
        ax.plot(ours - offset, ".", ms=3, label=f"nlos_cl - {offset:+.3f} m")
        ax.set(title=letter, xlabel="exposure", ylabel="range to the wall spot (m)")
        ax.legend(fontsize=7)
    return save(fig, out, "real-keyhole", dpi=70)


def _walk_figure(series, out) -> str:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5, 4), layout="constrained")
    pf, ours = series["reference"], series["ours"]
    ax.plot(pf[:, 0], pf[:, 2], "-", color="0.5", lw=1, label="authors' particle filter (mean)")
    ax.plot(ours[:, 0], ours[:, 2], ".", ms=3, label="nlos_cl track (confirmed)")
    if "lagged" in series:
        ax.plot(series["lagged"][:, 0], series["lagged"][:, 2], "-", lw=0.8,
                label="nlos_cl, fixed lag (--lag)")
    ax.plot([0], [0], "k^", label="sensor side (wall spots near 0)")
    ax.set(xlabel="X (m, the file's frame)", ylabel="Z (m, away from the wall)",
           title="walk, top view", aspect="equal")
    ax.legend(fontsize=7)
    return save(fig, out, "real-walk", dpi=70)


def _table(header, rows) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header),
            *["| " + " | ".join(str(c) for c in row) + " |" for row in rows], ""]


def _yes(ok) -> bool:
    return bool(ok)


def _found(row, measured: str) -> str:
    """What a located case measured, or that nothing was detected (no position is made up
    from the argmax of noise)."""
    return measured if row.get("detected", True) else "not detected (no return above the noise)"


def goals(summary) -> list[tuple]:
    """(dataset, goal, measured, met) per goal of real.yaml that the run measured."""
    cfg, sec, out = summary["config"], summary["sections"], []
    if sec.get("ccsocr"):
        low, high = cfg["ccsocr"]["goal"]["depth_m"]
        for r in sec["ccsocr"]:
            out.append(("CC-SOCR " + r["case"], f"depth {low}-{high} m in <= "
                        f"{cfg['ccsocr']['goal']['max_s']:g} s",
                        _found(r, f"{r['depth_m']} m in {r['seconds']} s"), _yes(r["met"])))
    for r in sec.get("lct") or []:
        out.append(("LCT " + r["case"], f"depth within {cfg['lct']['goal']['depth_m']} m of "
                    "the backprojection", _found(r, f"{r['depth_error_m']} m"), _yes(r["met"])))
    g = cfg["keyhole"]["goal"]
    for r in sec.get("keyhole") or []:
        out.append(("Keyhole " + r["case"], f"corr >= {g['corr']}, RMS <= {g['rms_m']} m",
                    f"{r['corr']}, {r['rms_m']} m", _yes(r["met"])))
    walk = sec.get("walk") or []
    for r in walk[:1]:  # the causal filter's row: what the tracker reports as it goes
        g = cfg["walk"]["goal"]
        out += [("walk", f">= {g['fps']:g} frames/s", f"{r['frames_per_s']}",
                 _yes(r["met"]["fps"])),
                ("walk", f"{g['ids']} track id throughout", f"{r['track_ids']}",
                 _yes(r["met"]["ids"])),
                ("walk", "smoother than the particle filter (median frame-to-frame step)",
                 f"{r['jitter_ours_m']} m vs {r['jitter_pf_m']} m", _yes(r["met"]["smoother"]))]
    for r in walk[1:2]:  # the fixed-lag row: real time, with latency
        out.append((r["case"], "smoother than the particle filter, with "
                    f"{cfg['walk']['lag_frames']} frames of latency",
                    f"{r['jitter_ours_m']} m vs {r['jitter_pf_m']} m", _yes(r["met"]["smoother"])))
    return out


def page(result, fig_dir: str) -> str:
    """The markdown page; figures linked under `fig_dir` (relative to the page)."""
    s = result.summary
    lines = [f"# {result.title}", "", s["header"], "",
             "Each dataset is read as `nlos-cl convert` reads it (`nl.read_dataset`) and "
             "located (`nl.locate_capture`) or tracked (`nlos-cl track`'s Tracker) with the "
             "library's defaults; every time is measured in this run, on this machine.", ""]
    for name, title in SECTION_TITLES.items():
        lines += [f"## {title}", ""]
        rows = s["sections"].get(name)
        c = s["config"][name]
        lines += [f"Geometry: {c['geometry']}.", "", f"Truth: {c['truth']}.", ""]
        if name not in s["sections"]:
            lines += ["Not in this run (--quick leaves it out).", ""]
            continue
        if rows is None:
            lines += ["The dataset is absent here: not run.", ""]
            continue
        keys = [k for k in rows[0] if k != "met"]
        lines += _table(keys, [[_cell(r[k]) for k in keys] for r in rows])
        if c.get("note"):
            lines += [c["note"], ""]
        figure = {"keyhole": "real-keyhole.png", "walk": "real-walk.png"}.get(name)
        if figure in result.figures:
            lines += [f"![{name}]({fig_dir}/{figure})", ""]
    return "\n".join(lines)


def _cell(v) -> str:
    if isinstance(v, float) and not np.isfinite(v):
        return "-"
    return "-" if v is None else str(v)
