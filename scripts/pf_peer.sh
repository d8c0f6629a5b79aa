#!/usr/bin/env bash
# A timed peer: the consumer-nlos authors' particle-filter tracker (MIT,
# ../shared/peers/consumer-nlos, PEER.md) in its own venv .venv-pf (torch CPU, opencv headless,
# seaborn, scipy, tqdm, pyyaml, and kornia: train/score.py imports it, requirements.txt omits
# it), run by scripts/pf_peer.py on the walk
# (../shared/realdata/consumer-nlos) in a temporary copy, beside `nlos-cl track` on the same
# frames. Not part of .ci/run: it installs ~200 MB and runs for minutes.
# Skips (exit 0) with a clear message when torch cannot be installed or the data are absent.
# NLOS_CL_PYTHON: the python that has nlos_cl (default: ./.venv/bin/python);
# NLOS_CL_REALDATA: the measured datasets (default ../shared/realdata);
# NLOS_CL_PEERS: the peers' sources (default ../shared/peers).
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=.venv-pf
PY=${PYTHON:-python3}
export NLOS_CL_PYTHON=${NLOS_CL_PYTHON:-$PWD/.venv/bin/python}

if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c "import torch, cv2, seaborn, scipy, tqdm, yaml, kornia" 2>/dev/null; then
    "$PY" -m venv "$VENV"
    # torch's CPU build: from its own index where that is reachable, else a +cpu wheel from the
    # local wheel folder pip is configured with (PIP_FIND_LINKS); PyPI's default torch pulls
    # ~3 GB of CUDA libraries that a CPU run never loads.
    if ! "$VENV/bin/python" -m pip install --quiet --timeout 15 --retries 0 \
            --index-url https://download.pytorch.org/whl/cpu torch 2>/dev/null; then
        wheel=$(ls ${PIP_FIND_LINKS:-/nonexistent}/torch-*+cpu-*.whl 2>/dev/null | sort -V | tail -1 || true)
        if [ -z "$wheel" ] || ! "$VENV/bin/python" -m pip install --quiet "$wheel"; then
            echo "SKIP pf_peer: torch (CPU) cannot be installed: its index is unreachable and no local +cpu wheel"
            exit 0
        fi
    fi
    "$VENV/bin/python" -m pip install --quiet opencv-python-headless seaborn scipy tqdm pyyaml matplotlib kornia
fi
exec "$VENV/bin/python" scripts/pf_peer.py "$@"
