#!/usr/bin/env bash
# Install (scripts/setup.sh) and run the main job: the paper's scene located end to end.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/nlos-cl demo "$@"
