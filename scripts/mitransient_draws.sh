#!/usr/bin/env bash
# The estimators on mitransient renders of `reproduce draws`' one-target draws: see
# scripts/mitransient_draws.py. Usage: bash scripts/mitransient_draws.sh [--start I] [--count N]
# [--spp N] [--family one|closed] (results in $OUT, default out/mitransient-draws; builds
# .venv-mitransient and Debian's libllvm19: scripts/mitransient_env.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/mitransient_env.sh  # libllvm19 and .venv-mitransient
OUT=${OUT:-out/mitransient-draws}
mkdir -p "$OUT"
.venv/bin/python scripts/mitransient_draws.py export --out "$OUT" "$@"
.venv-mitransient/bin/python scripts/mitransient_draws.py render --out "$OUT" "$@"
.venv/bin/python scripts/mitransient_draws.py locate --out "$OUT" "$@"
