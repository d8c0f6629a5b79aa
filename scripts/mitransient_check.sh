#!/usr/bin/env bash
# Independent check of the forward model against mitransient (Mitsuba 3 transient renders).
# Its own venv (.venv-mitransient); Debian 12's LLVM 15 crashes drjit: libllvm19 from apt.
# Usage: bash scripts/mitransient_check.sh [--spp N] [--splits N] [--scenes plate,box,...] [--facet M]
# (results in $OUT, default out/mitransient)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/mitransient_env.sh  # libllvm19 and .venv-mitransient
# nlos_cl runs in its own venv; the renders in this one; they meet in .npz files.
OUT=${OUT:-out/mitransient}
mkdir -p "$OUT"
.venv/bin/python scripts/mitransient_check.py export --out "$OUT" "$@"
.venv-mitransient/bin/python scripts/mitransient_check.py render --out "$OUT" "$@"
.venv/bin/python scripts/mitransient_check.py compare --out "$OUT" "$@"
