#!/usr/bin/env bash
# Type-check the seams between layers (pyproject.toml's [tool.mypy] files: the Protocols
# Estimator, Shape, MotionModel, NoiseModel and Backend where they are used). mypy is a test
# extra (scripts/setup.sh --test).
set -euo pipefail
cd "$(dirname "$0")/.."
exec .venv/bin/python -m mypy
