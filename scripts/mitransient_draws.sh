#!/usr/bin/env bash
# The estimators on mitransient renders of `reproduce draws`' one-target draws: see
# scripts/mitransient_draws.py. Usage: bash scripts/mitransient_draws.sh [--start I] [--count N]
# [--spp N] (results in $OUT, default out/mitransient-draws; builds .venv-mitransient and
# Debian's libllvm19 as scripts/mitransient_check.sh does)
set -euo pipefail
cd "$(dirname "$0")/.."
if ! ls /usr/lib/x86_64-linux-gnu/libLLVM.so.19* >/dev/null 2>&1; then
    ${SUDO:-$(command -v sudo || true)} apt-get install -y libllvm19
fi
export DRJIT_LIBLLVM_PATH=${DRJIT_LIBLLVM_PATH:-$(ls /usr/lib/x86_64-linux-gnu/libLLVM.so.19* | head -1)}
if [ ! -x .venv-mitransient/bin/python ]; then
    python3 -m venv .venv-mitransient
    .venv-mitransient/bin/pip install -q mitransient==1.3.1 numpy trimesh
fi
OUT=${OUT:-out/mitransient-draws}
mkdir -p "$OUT"
.venv/bin/python scripts/mitransient_draws.py export --out "$OUT" "$@"
.venv-mitransient/bin/python scripts/mitransient_draws.py render --out "$OUT" "$@"
.venv/bin/python scripts/mitransient_draws.py locate --out "$OUT" "$@"
