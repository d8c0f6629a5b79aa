"""`nlos-cl bench` on the command line."""
from __future__ import annotations

from pathlib import Path


def main(args) -> int:
    """Check --out's files before the bench's minutes of work (bench.report.check_out: never
    over a file nlos_cl did not write unless --force), then bench and write them."""
    from .bench import run
    from .bench.report import check_out
    out = Path(args.out) if args.out else None
    if out is not None and out.is_dir():
        check_out(out, args.force)
    print(run(args.device, smoke=args.smoke, out_dir=out, force=args.force))
    return 0
