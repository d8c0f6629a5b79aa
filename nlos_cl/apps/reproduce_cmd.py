"""`nlos-cl reproduce` on the command line. `reproduce all` (the paper's experiments) writes
paper-results.md; `reproduce beyond` writes beyond-the-paper.md (OUT/ unless --doc);
`reproduce tracking --doc docs/tracking.md` fills that page's tables."""
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


def _write_doc(rp, args, settings, results, wall) -> None:
    if args.name == "tracking":  # its sections go between docs/tracking.md's markers
        if args.doc:
            from .reproduce.tracking import write_doc
            write_doc(results[0], Path(args.doc))
        return
    if args.name == "beyond":
        from .reproduce.beyond_report import write_beyond_report
        doc = Path(args.doc) if args.doc else Path(args.out) / "beyond-the-paper.md"
        write_beyond_report(results[0], settings, doc, Path(args.out), wall)
    elif args.name == "all" or args.doc:
        doc = Path(args.doc) if args.doc else Path(args.out) / "paper-results.md"
        rp.write_report(results, settings, doc, Path(args.out), wall)


def main(args) -> int:
    from . import reproduce as rp
    settings = rp.Settings.make(quick=args.quick, seeds=args.seeds)
    start = time.perf_counter()
    options = {}
    if args.only:
        options["only"] = args.only
    if args.cold:
        options["cold"] = True
    results = rp.run(args.name, settings, Path(args.out), **options)
    wall = time.perf_counter() - start
    _write_doc(rp, args, settings, results, wall)
    if args.json:
        print(json.dumps(_finite(results[0].summary)) if args.name == "beyond"
              else rp.summary_json(results))
    else:
        for r in results:
            print(f"{r.name}: {r.title} ({r.seconds:.1f} s) -> {args.out}/{r.name}.csv "
                  + " ".join(r.figures))
            print("  " + json.dumps(r.summary)[:600])
        print(f"wall time {wall:.1f} s")
    return 0
