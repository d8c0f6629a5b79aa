#!/usr/bin/env bash
# Peers for `nlos-cl bench`: y-tal's backprojection (PyPI `y-tal`, imported as `tal`; it pins
# numpy < 2, so it lives in its own venv, .venv-peers) timed on the same signals and grids as
# nlos_cl's scoring rows. Writes docs/results/performance/performance-peers.json, which
# `nlos-cl bench` reads when present (a column beside nlos_cl's own times; ratios are only
# comparable from one machine).
# Usage: scripts/bench_peers.sh [--smoke]      NLOS_CL_PYTHON: nlos_cl's python (./.venv)
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=.venv-peers
PY=${PYTHON:-python3}
NLOS_PY=${NLOS_CL_PYTHON:-$PWD/.venv/bin/python}
if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c "import tal" 2>/dev/null; then
    "$PY" -m venv "$VENV"
    if ! "$VENV/bin/python" -m pip install --quiet y-tal "numpy<2"; then
        echo "SKIP bench_peers: y-tal could not be installed (no package registry?)"; exit 0
    fi
fi
inputs=$(mktemp -d)/peers_inputs.npz
"$NLOS_PY" scripts/bench_peers.py write-inputs "$inputs" "$@"
"$VENV/bin/python" scripts/bench_peers.py time-ytal "$inputs" \
    docs/results/performance/performance-peers.json
