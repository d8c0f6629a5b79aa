"""The red team's route into the Python API (issue 59): `python redteam_api.py FUNCTION PATH
[KEY=VALUE ...]` calls nlos_cl.FUNCTION(PATH, **options) as a user's script would, and reports
an InputError (the library's documented exception for bad input) as the CLI does, on one line
(`nlos-cl api: ...`, exit 2); anything else raised propagates as a traceback. A success prints
one line saying what came back."""
from __future__ import annotations

import json
import sys


def main(argv: list[str]) -> int:
    import nlos_cl as nl
    from nlos_cl.core.errors import InputError
    name, path, *pairs = argv
    options = {k: json.loads(v) for k, v in (p.split("=", 1) for p in pairs)}
    try:
        got = getattr(nl, name)(path, **options)
    except InputError as exc:
        print(f"nlos-cl api: {exc}", file=sys.stderr)
        return 2
    print(f"{name}: returned {type(got).__name__} {str(got)[:200]!r}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
