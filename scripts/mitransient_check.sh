#!/usr/bin/env bash
# Independent check of the forward model against mitransient (Mitsuba 3 transient renders).
# Its own venv (.venv-mitransient); Debian 12's LLVM 15 crashes drjit: libllvm19 from apt.
# Usage: bash scripts/mitransient_check.sh [--spp N] [--splits N] [--scenes plate,box,...] [--facet M]
# (results in $OUT, default out/mitransient)
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
# nlos_cl runs in its own venv; the renders in this one; they meet in .npz files.
OUT=${OUT:-out/mitransient}
mkdir -p "$OUT"
.venv/bin/python scripts/mitransient_check.py export --out "$OUT" "$@"
.venv-mitransient/bin/python scripts/mitransient_check.py render --out "$OUT" "$@"
.venv/bin/python scripts/mitransient_check.py compare --out "$OUT" "$@"
