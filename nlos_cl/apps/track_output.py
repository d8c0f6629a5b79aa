"""What `nlos-cl track` prints and keeps, one frame at a time, all from the frame's one entry
(the JSON object, in the file's own frame): a JSON line (--json), text lines (the default: one
per track, position ± 1 sd per axis), and rows of a CSV table (--csv FILE, beside either).

The CSV is tidy: one row per track, measurement and truth of each frame, columns
frame, t_s, kind (track | measurement | truth), id, status, the file's three axes (X, Y, Z for
a y-tal file), sd_ and v_ of each (track rows), and estimate (filter | smoothed | lag N). A
range track (one confocal spot) has its own columns: frame, t_s, range_m, range_sd_m,
range_speed_m_s, measured_range_m, estimate."""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

RANGE_COLUMNS = ["frame", "t_s", "range_m", "range_sd_m", "range_speed_m_s",
                 "measured_range_m", "estimate"]


def check_csv_path(args) -> None:
    """Before any tracking: --csv names a .csv in an existing folder that nlos_cl may write."""
    from ..core.errors import require
    from ..io.safe_write import require_writable
    path = Path(args.csv)
    require(path.suffix.lower() == ".csv", "--csv", f"{path} does not end in .csv",
            "pass e.g. tracks.csv")
    require(path.parent.is_dir(), "--csv", f"the folder {path.parent} does not exist",
            "pass a path in an existing folder")
    require_writable(path, force=args.force, what="--csv", kind="a track table")


def _estimate(entry) -> str:
    if entry.get("smoothed"):
        return "smoothed"
    return f"lag {entry['lag_frames']}" if "lag_frames" in entry else "filter"


def _sds(covariance) -> list:
    """Each axis's 1 sd from a JSON covariance (None: unobservable or not given)."""
    if covariance is None:
        return [None] * 3
    return [None if row[i] is None or not math.isfinite(row[i]) else
            float(f"{math.sqrt(max(row[i], 0.0)):.6g}") for i, row in enumerate(covariance)]


def _axis(name, value, sd) -> str:
    return f"{name} {value:.4f}" + (" ± unobservable" if sd is None else f" ± {sd:.4f}")


class Outputs:
    """Where each frame's entry goes: stdout (JSON or text) and the CSV file object, if any."""

    def __init__(self, as_json: bool, axes, csv_file=None, ranges: bool = False):
        self.as_json, self.axes = as_json, list(axes)
        self.writer = None if csv_file is None else csv.writer(csv_file)
        if self.writer is not None:
            self.writer.writerow(RANGE_COLUMNS if ranges else
                                 ["frame", "t_s", "kind", "id", "status", *self.axes,
                                  *(f"sd_{a}" for a in self.axes),
                                  *(f"v_{a}" for a in self.axes), "estimate"])

    def frame(self, entry: dict) -> None:
        """A position track's frame (apps/track.py's _entry)."""
        if self.as_json:
            print(json.dumps(entry), flush=True)
        else:
            print(self._text(entry), flush=True)
        if self.writer is not None:
            head, how = [entry["frame"], entry["t_s"]], _estimate(entry)
            for t in entry["tracks"]:
                status = "static" if t.get("static") else t["status"]
                self.writer.writerow([*head, "track", t["id"], status, *t["position"],
                                      *_sds(t["covariance"]), *t["velocity"], how])
            for m in entry["measurements"]:
                self.writer.writerow([*head, "measurement", "", "", *m, *[""] * 6, ""])
            for p in entry["truths"] or []:
                self.writer.writerow([*head, "truth", "", "", *p, *[""] * 6, ""])

    def _text(self, entry) -> str:
        head = f"frame {entry['frame']}, t {entry['t_s']:.3f} s"
        if not entry["tracks"]:
            return f"{head}: no track" + ("" if entry["detected"] else " (no target signal)")
        how = _estimate(entry)
        return "\n".join(
            f"{head}: track {t['id']} ({t['status']}{', static' if t.get('static') else ''}"
            f"{'' if how == 'filter' else ', ' + how}) "
            + ", ".join(_axis(a, v, s) for a, v, s in
                        zip(self.axes, t["position"], _sds(t["covariance"]))) + " m"
            for t in entry["tracks"])

    def range(self, entry: dict) -> None:
        """A range track's frame (one confocal spot)."""
        if self.as_json:
            print(json.dumps(entry), flush=True)
        else:
            head = f"frame {entry['frame']}, t {entry['t_s']:.3f} s"
            r, sd, seen = entry["range_m"], entry["range_sd_m"], entry["measured_range_m"]
            print(f"{head}: no range yet (no return)" if r is None else
                  f"{head}: range {r:.4f} ± {sd:.4f} m" + (
                      f" (measured {seen:.4f})" if seen is not None else " (no return)"))
        if self.writer is not None:
            self.writer.writerow([entry[k] if entry.get(k) is not None else "" for k in
                                  RANGE_COLUMNS[:-1]] + [_estimate(entry)])
