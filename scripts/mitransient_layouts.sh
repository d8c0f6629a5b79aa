#!/usr/bin/env bash
# The capture layouts (one laser, confocal, paired, exhaustive) on nlos_cl simulations and
# mitransient renders of the same targets: see scripts/mitransient_layouts.py. Usage:
# bash scripts/mitransient_layouts.sh [--start I] [--count N] [--spp N] [--jobs N]
# [--doc docs/results/rendered/layouts-rendered.md] (results in $OUT, default
# out/mitransient-layouts; builds .venv-mitransient and Debian's libllvm19:
# scripts/mitransient_env.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/mitransient_env.sh  # libllvm19 and .venv-mitransient
OUT=${OUT:-out/mitransient-layouts}
mkdir -p "$OUT"
.venv/bin/python scripts/mitransient_layouts.py export --out "$OUT" "$@"
.venv-mitransient/bin/python scripts/mitransient_layouts.py render --out "$OUT" "$@"
.venv/bin/python scripts/mitransient_layouts.py locate --out "$OUT" "$@"
