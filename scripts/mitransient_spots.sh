#!/usr/bin/env bash
# Finite (disk) spots against mitransient: see scripts/mitransient_spots.py.
# Usage: bash scripts/mitransient_spots.sh [--spp N] [--splits N]   (results in $OUT, default
# out/mitransient; needs the .venv-mitransient that mitransient_check.sh builds)
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -x .venv-mitransient/bin/python ]; then
    echo "run scripts/mitransient_check.sh once first (it builds .venv-mitransient)" >&2; exit 1
fi
export DRJIT_LIBLLVM_PATH=${DRJIT_LIBLLVM_PATH:-$(ls /usr/lib/x86_64-linux-gnu/libLLVM.so.19* | head -1)}
OUT=${OUT:-out/mitransient}
mkdir -p "$OUT"
.venv/bin/python scripts/mitransient_spots.py export --out "$OUT" "$@"
.venv-mitransient/bin/python scripts/mitransient_spots.py render --out "$OUT" "$@"
.venv/bin/python scripts/mitransient_spots.py compare --out "$OUT" "$@"
