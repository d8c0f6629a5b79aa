#!/usr/bin/env bash
# Intel's CPU OpenCL runtime from PyPI (intel-opencl-rt, plus intel-cmplr-lib-rt, which it
# needs but does not declare) as a SECOND OpenCL implementation beside PoCL, for checking the
# kernels on another compiler. Installs into a prefix of its own (never into .venv), then
# prints the export line that makes pyopencl list PoCL and Intel's CPU device in one process:
#
#   eval "$(scripts/intel_opencl.sh)"         # or: . /tmp/nlos_cl-intel-opencl/env.sh
#   PYOPENCL_CTX=intel .venv/bin/python -m pytest -q tests/
#
# Idempotent; when already installed it only refreshes the ICD folder and re-checks (~1 s).
# Needs .venv from scripts/setup.sh. Messages go to stderr, the export line to stdout.
# Settings: NLOS_INTEL_OCL_PREFIX (default /tmp/nlos_cl-intel-opencl; about 810 MB),
#           NLOS_INTEL_OCL_VERSION (default 2026.2.0, the version this was tested with).
#
# Why it is done this way:
# * pip --target loses the libraries: the wheels ship them as data files (<prefix>/lib), which
#   --target drops, so this uses --prefix, with --ignore-installed so that tbb & co. are put
#   in the prefix even if .venv has them.
# * The .icd file in the wheel names a conda placeholder (/opt/anaconda1anaconda2anaconda3),
#   so this writes its own ICD folder: links to the system's .icd files (PoCL) plus one naming
#   <prefix>/lib/libintelocl.so, and points OCL_ICD_VENDORS (read by ocl-icd, pyopencl's
#   bundled copy included, and by Khronos' loader) at it. An ICD in pyopencl's own folder
#   (PyPI's pocl-binary-distribution) stays visible either way.
# * With both visible, the default device stays PoCL (same type; PoCL's version ranks higher
#   in nlos_cl.device.devices); PYOPENCL_CTX=intel (platform "Intel(R) OpenCL") selects Intel's.
set -euo pipefail
cd "$(dirname "$0")/.."

prefix=${NLOS_INTEL_OCL_PREFIX:-/tmp/nlos_cl-intel-opencl}
version=${NLOS_INTEL_OCL_VERSION:-2026.2.0}
py=.venv/bin/python
say() { echo "intel_opencl: $*" >&2; }

[ -x "$py" ] || { say "no .venv here; run scripts/setup.sh --test first"; exit 1; }

lib=$prefix/lib/libintelocl.so
stamp=$prefix/.nlos_cl-installed-$version
if [ ! -e "$stamp" ] || [ ! -e "$lib" ]; then
  say "installing intel-opencl-rt==$version + intel-cmplr-lib-rt==$version into $prefix"
  mkdir -p "$prefix"
  start=$(date +%s)
  "$py" -m pip install -q --disable-pip-version-check --no-warn-script-location \
      --ignore-installed --prefix "$prefix" \
      "intel-opencl-rt==$version" "intel-cmplr-lib-rt==$version" >&2
  [ -e "$lib" ] || { say "pip finished but $lib is missing"; exit 1; }
  touch "$stamp"
  say "installed in $(( $(date +%s) - start )) s, $(du -sh "$prefix" | cut -f1)"
fi

# ICD folder: the system's ICDs (PoCL) + Intel's, with an absolute path. Updated in place
# (no moment with an empty folder for a process that is loading it right now).
vendors=$prefix/vendors
mkdir -p "$vendors"
system_vendors=/etc/OpenCL/vendors
for icd in "$system_vendors"/*.icd; do
  [ -e "$icd" ] || continue
  case "$(basename "$icd")" in nlos_cl-*) continue ;; esac
  ln -sfn "$icd" "$vendors/$(basename "$icd")"
done
for link in "$vendors"/*.icd; do  # drop links to ICDs since removed from the system
  if [ -L "$link" ] && [ ! -e "$link" ]; then rm -f "$link"; fi
done
intel_icd=$vendors/nlos_cl-intel-cpu-pypi.icd
[ "$(cat "$intel_icd" 2>/dev/null)" = "$lib" ] || echo "$lib" > "$intel_icd"

env_line="export OCL_ICD_VENDORS=$(printf %q "$vendors")"
echo "$env_line" > "$prefix/env.sh"

# Check: both implementations must now be listed in one process.
OCL_ICD_VENDORS=$vendors "$py" - >&2 <<'EOF'
import sys
from nlos_cl.device.devices import list_devices
entries = list_devices()
for e in entries:
    print("intel_opencl:   " + e.label)
names = [e.platform.name for e in entries]
if not any("Intel" in n for n in names):
    sys.exit("intel_opencl: Intel's platform is NOT listed (see above); "
             "OCL_ICD_DEBUG=7 shows what the ICD loader tried")
if not any("Portable Computing Language" in n for n in names):
    print("intel_opencl: warning: no PoCL platform listed beside Intel's")
EOF
say "ok; select Intel's device with PYOPENCL_CTX=intel (env also in $prefix/env.sh)"
echo "$env_line"
