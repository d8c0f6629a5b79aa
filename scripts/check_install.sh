#!/usr/bin/env bash
# A non-editable install (pip install .) into a fresh venv must ship kernels/ and pass
# `nlos-cl info` (which builds every kernel and checks it against its NumPy twin), run from a
# folder where the checkout's sources cannot be imported by accident.
set -euo pipefail
repo="$(cd "$(dirname "$0")/.." && pwd)"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
python3 -m venv "$tmp/venv"
"$tmp/venv/bin/python" -m pip install -q "$repo"
cd "$tmp"
"$tmp/venv/bin/python" -c 'import nlos_cl.device.runtime as r, pathlib; print("kernels from", r.resources.files("nlos_cl.kernels"))'
"$tmp/venv/bin/nlos-cl" info
