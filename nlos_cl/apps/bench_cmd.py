"""`nlos-cl bench` on the command line."""
from __future__ import annotations

from pathlib import Path


def main(args) -> int:
    from .bench import run
    print(run(args.device, smoke=args.smoke, out_dir=Path(args.out) if args.out else None))
    return 0
