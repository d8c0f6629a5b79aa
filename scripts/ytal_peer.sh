#!/usr/bin/env bash
# Real peers: y-tal (PyPI `y-tal`, imported as `tal`; it wants numpy < 2) in its own venv
# .venv-ytal, checked both ways against nlos_cl by scripts/ytal_peer.py:
#   (a) y-tal reads a capture nlos_cl wrote, and its backprojection peaks at the target;
#   (b) nlos_cl reads captures y-tal wrote (targets on both sides of X = 0) and locates them.
# Skips (exit 0) with a clear message only when the package registry cannot be reached.
# NLOS_CL_PYTHON: the python that has nlos_cl (default: ./.venv/bin/python).
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=.venv-ytal
PY=${PYTHON:-python3}
export NLOS_CL_PYTHON=${NLOS_CL_PYTHON:-$PWD/.venv/bin/python}

if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c "import tal" 2>/dev/null; then
    "$PY" -m venv "$VENV"
    probe=$(mktemp -d)
    if ! "$VENV/bin/python" -m pip download --quiet --no-deps --dest "$probe" y-tal >/dev/null 2>&1; then
        rm -rf "$probe"
        echo "SKIP ytal_peer: the package registry (PyPI) cannot be reached, so y-tal cannot be installed"
        exit 0
    fi
    rm -rf "$probe"
    "$VENV/bin/python" -m pip install --quiet --upgrade pip
    "$VENV/bin/python" -m pip install --quiet y-tal "numpy<2"
fi
exec "$VENV/bin/python" scripts/ytal_peer.py "$@"
