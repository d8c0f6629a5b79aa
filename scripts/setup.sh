#!/usr/bin/env bash
# Install everything nlos_cl needs into ./.venv on a fresh Debian machine with Python 3.11:
# an OpenCL runtime (Debian's PoCL 3.1 where apt is available: 5-10x faster than PyPI's PoCL
# 3.0-rc2, which never inlines builtins such as exp; PyPI's pocl-binary-distribution otherwise)
# and the Python package. Usage: scripts/setup.sh [--test]   (--test: editable, with test extras)
set -euo pipefail
cd "$(dirname "$0")/.."

sudo_if_needed() { if [ "$(id -u)" -eq 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else return 1; fi; }

apt_packages=()
if command -v apt-get >/dev/null 2>&1; then
  dpkg -s pocl-opencl-icd >/dev/null 2>&1 || apt_packages+=(pocl-opencl-icd ocl-icd-libopencl1)
  python3 -c 'import ensurepip' >/dev/null 2>&1 || apt_packages+=(python3-venv)
fi
pip_pocl=()
if [ ${#apt_packages[@]} -gt 0 ]; then
  echo "setup: apt-get install ${apt_packages[*]}"
  if ! { sudo_if_needed apt-get update -qq && sudo_if_needed env DEBIAN_FRONTEND=noninteractive \
           apt-get install -y -qq "${apt_packages[@]}" >/dev/null; }; then
    echo "setup: apt-get failed; falling back to PyPI's pocl-binary-distribution (slower)" >&2
    pip_pocl=(pocl-binary-distribution)
  fi
elif ! command -v apt-get >/dev/null 2>&1; then
  pip_pocl=(pocl-binary-distribution)
fi

# PoCL lists zero devices, silently, when it cannot create its cache folder.
if [ -z "${XDG_CACHE_HOME:-}${POCL_CACHE_DIR:-}" ] && ! mkdir -p "$HOME/.cache" 2>/dev/null; then
  echo "setup: ~/.cache is not writable; export POCL_CACHE_DIR=/tmp/pocl-cache before running" >&2
fi

[ -x .venv/bin/python ] || python3 -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip
if [ "${1:-}" = "--test" ]; then
  .venv/bin/python -m pip install -q -e ".[test]" "${pip_pocl[@]}"
else
  .venv/bin/python -m pip install -q . "${pip_pocl[@]}"
fi
echo "setup: done (.venv)"
