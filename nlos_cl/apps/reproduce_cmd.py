"""`nlos-cl reproduce` on the command line."""
from __future__ import annotations

import json
import time
from pathlib import Path


def main(args) -> int:
    from . import reproduce as rp
    settings = rp.Settings.make(quick=args.quick, seeds=args.seeds)
    start = time.perf_counter()
    results = rp.run(args.name, settings, Path(args.out))
    wall = time.perf_counter() - start
    if args.name == "all" or args.doc:
        doc = Path(args.doc) if args.doc else Path(args.out) / "paper-results.md"
        rp.write_report(results, settings, doc, Path(args.out), wall)
    if args.json:
        print(rp.summary_json(results))
    else:
        for r in results:
            print(f"{r.name}: {r.title} ({r.seconds:.1f} s) -> {args.out}/{r.name}.csv "
                  + " ".join(r.figures))
            print("  " + json.dumps(r.summary)[:600])
        print(f"wall time {wall:.1f} s")
    return 0
