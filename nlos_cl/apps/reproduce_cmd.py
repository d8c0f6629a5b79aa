"""`nlos-cl reproduce` on the command line. `reproduce all` (the paper's experiments) writes
paper-results.md; `reproduce beyond` writes beyond-the-paper.md (OUT/ unless --doc);
`reproduce tracking --doc docs/tracking.md` fills that page's tables; `reproduce real --doc
docs/results/real-data/real-data.md` writes that page (figures in docs/results/real-data/real/;
OUT/real-data.md always); `reproduce draws` and `reproduce flood` write OUT/NAME.md, and with
--doc that page there (flood: its flood.csv beside it)."""
from __future__ import annotations

import json
import math
import time
from pathlib import Path


def _finite(value):
    """NaN (a failed fit) as null, so that --json prints strict JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


def _doc_path(args) -> Path | None:
    """The page this run writes (tracking's is spliced by its own writer between markers)."""
    if args.name == "beyond":
        return Path(args.doc) if args.doc else Path(args.out) / "beyond-the-paper.md"
    if args.name == "real":
        return Path(args.doc) if args.doc else None  # OUT/real-data.md is always written
    if args.name != "tracking" and (args.name == "all" or args.doc):
        return Path(args.doc) if args.doc else Path(args.out) / "paper-results.md"
    return None


def _ours(names):
    """The files of OUT a run of `names` writes: those whose name starts with an experiment's
    (fig5.csv, fig7a.png, beyond-summary.csv, tracking-speed.csv...)."""
    return lambda p: p.is_file() and p.name.startswith(tuple(names))


def _check_outputs(args) -> list:
    """Before any experiment runs (minutes to hours): the page, and every existing file of OUT
    that the run may replace, must be nlos_cl's (safe_write's manifest, or a generated page's
    mark) or --force; a user's own fig5.csv or notes.md is refused now, not lost later. The
    experiments' CSV and figure writers are not atomic, so their names are matched by prefix
    (conservative: a user's fig5-notes.txt in OUT is refused too). Returns the names."""
    from ..io.safe_write import is_generated_doc, require_writable
    from .reproduce import PAPER_EXPERIMENTS
    names = list(PAPER_EXPERIMENTS) if args.name == "all" else [args.name]
    doc = _doc_path(args)
    if doc is not None and doc.parent.is_dir():
        require_writable(doc, keep_unless=is_generated_doc, force=args.force, what="--doc",
                         kind="a page nlos_cl generated")
    out = Path(args.out)
    if out.is_dir() and not args.force:
        for path in sorted(filter(_ours(names), out.iterdir())):
            if doc is None or path.resolve() != doc.resolve():
                require_writable(path, what="--out", kind="a file nlos-cl reproduce wrote")
    return names


def _record_outputs(out: Path, names) -> None:
    """Note the files the experiments wrote in OUT as nlos_cl's (safe_write.record), so the
    next run may replace them without --force."""
    from ..io.safe_write import record
    for path in filter(_ours(names), out.iterdir() if out.is_dir() else ()):
        record(path)


def _write_doc(rp, args, settings, results, wall) -> None:
    if args.name in ("tracking", "draws", "flood", "scenarios"):  # own writers (tracking: markers)
        if args.doc:
            from importlib import import_module
            writer = import_module(f".reproduce.{args.name}", __package__).write_doc
            writer(results[0], Path(args.doc))
        return
    if args.name == "real":
        if args.doc:
            from .reproduce.real import write_doc
            write_doc(results[0], Path(args.doc), Path(args.out), args.force)
        return
    if args.name == "beyond":
        from .reproduce.beyond.report import write_beyond_report
        write_beyond_report(results[0], settings, _doc_path(args), Path(args.out), wall,
                            args.force)
    elif args.name == "all" or args.doc:
        rp.write_report(results, settings, _doc_path(args), Path(args.out), wall, args.force)


def main(args) -> int:
    from . import reproduce as rp
    settings = rp.Settings.make(quick=args.quick, seeds=args.seeds)
    names = _check_outputs(args)
    start = time.perf_counter()
    options = {}
    if args.only:
        options["only"] = args.only
    if args.cold:
        options["cold"] = True
    if getattr(args, "draws", None):  # draws: scenes per family
        options["draws"] = args.draws
    if getattr(args, "jobs", None):  # draws: worker processes
        options["jobs"] = args.jobs
    if getattr(args, "data", None):  # real: the measured datasets' folder
        options["data"] = args.data
    results = rp.run(args.name, settings, Path(args.out), **options)
    _record_outputs(Path(args.out), names)
    wall = time.perf_counter() - start
    _write_doc(rp, args, settings, results, wall)
    if args.json:
        print(json.dumps(_finite(results[0].summary)) if args.name == "beyond"
              else rp.summary_json(results))
    else:
        from .reproduce.report import summary_text
        print(summary_text(results, Path(args.out), wall))
    return 0
