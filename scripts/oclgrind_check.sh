#!/usr/bin/env bash
# Run every OpenCL kernel under the oclgrind simulator with out-of-bounds and data-race
# checking, and fail if oclgrind reports anything.
#
# oclgrind never changes a program's exit status: it writes what it finds to its log. So this
# script (1) runs a canary kernel with a known race and a known out-of-bounds write and
# requires both in that log (proof that the checks are on and the log is read), then (2) runs
# scripts/oclgrind_check.py (every kernel of kernels/*.cl on tiny inputs, compared with the
# NumPy twins) and requires an empty log and a zero exit status.
#
# Usage: scripts/oclgrind_check.sh   (extra arguments go to oclgrind_check.py)
# Environment: OCLGRIND_CHECK_DIR  folder for the logs (default: a new temporary folder)
#              OCLGRIND_CHECK_TIMEOUT  seconds for the main run (default 900)
# Needs ./.venv (scripts/setup.sh --test); installs the Debian package oclgrind if missing.
set -euo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)

sudo_if_needed() { if [ "$(id -u)" -eq 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else return 1; fi; }

find_icd() {
  local so
  so=$(dpkg -L oclgrind 2>/dev/null | grep -m1 '/liboclgrind-rt-icd\.so$' || true)
  for f in "$so" /usr/lib/oclgrind/liboclgrind-rt-icd.so /usr/lib/x86_64-linux-gnu/liboclgrind-rt-icd.so \
           /usr/local/lib/liboclgrind-rt-icd.so /usr/local/lib/oclgrind/liboclgrind-rt-icd.so; do
    if [ -n "$f" ] && [ -f "$f" ]; then echo "$f"; return 0; fi
  done
  return 1
}

if ! icd=$(find_icd); then
  echo "oclgrind_check: installing oclgrind (apt-get)"
  export DEBIAN_FRONTEND=noninteractive
  if ! sudo_if_needed env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq oclgrind >/dev/null; then
    sudo_if_needed apt-get update -qq
    sudo_if_needed env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq oclgrind >/dev/null
  fi
  icd=$(find_icd) || { echo "oclgrind_check: oclgrind installed but liboclgrind-rt-icd.so not found" >&2; exit 2; }
fi
version=$(dpkg-query -W -f='${Version}' oclgrind 2>/dev/null || oclgrind --version 2>/dev/null | head -1 || echo unknown)

py=.venv/bin/python
if [ ! -x "$py" ]; then
  echo "oclgrind_check: no .venv here; run scripts/setup.sh --test first" >&2
  exit 2
fi

dir=${OCLGRIND_CHECK_DIR:-$(mktemp -d /tmp/oclgrind-check.XXXXXX)}
mkdir -p "$dir"
# oclgrind_check.py gives every OpenCL context its own log: <prefix>.<context>.
log="$dir/oclgrind.log"
canary_prefix="$dir/canary.log"
rm -f "$log".* "$canary_prefix".*

# Only the oclgrind device is visible; PoCL's cache fix in nlos_cl.device.devices is not needed, but a
# writable cache folder keeps every library quiet.
export XDG_CACHE_HOME=${XDG_CACHE_HOME:-/tmp/xdgcache-oclgrind}
export OCL_ICD_VENDORS="$icd"
export OCLGRIND_DATA_RACES=1
export OCLGRIND_UNIFORM_WRITES=1  # also report races whose racing writes store the same value
export OCLGRIND_NUM_THREADS=1     # one worker thread: findings are not interleaved in the log
export PYOPENCL_NO_CACHE=1
unset PYOPENCL_CTX OCLGRIND_QUICK OCLGRIND_UNINITIALIZED 2>/dev/null || true

# Summarise an oclgrind log: findings by kind and by kernel, then the first few verbatim.
summarise() {
  "$py" - "$@" <<'EOF'
import re, sys
from collections import Counter
blocks = []
for path in sys.argv[1:]:
    cur = None
    for line in open(path, errors="replace").read().splitlines():
        if line.strip() and (cur is None or not line[0].isspace()):  # a finding: column 0
            cur = [line]
            blocks.append(cur)
        elif cur is not None:
            cur.append(line)


def kind(head):
    h = head.strip().lower()
    m = re.match(r"invalid (read|write) of size \d+ at (\w+) memory", h)
    if m:
        return f"out-of-bounds {m[1]} ({m[2]} memory)"
    if "data race" in h:
        return h.split(" at ")[0]  # e.g. "read-write data race"
    if "uninitiali" in h:
        return "uninitialized value"
    if "runtime error" in h:
        return "OpenCL API error"
    if "divergence" in h:
        return "work-group divergence"
    if "errors generated" in h:
        return "note: oclgrind stopped reporting (too many errors)"
    return "other: " + head.strip()[:60]


by_kind, by_site = Counter(), Counter()
for b in blocks:
    k = kind(b[0])
    by_kind[k] += 1
    kern = next((ln.split(":", 1)[1].strip() for ln in b if ln.strip().startswith("Kernel:")), "-")
    at = next((ln.strip().rstrip(":") for ln in b if ln.strip().startswith("At line")), "")
    by_site[(k, kern, at)] += 1
print(f"  {len(blocks)} finding(s)")
for k, n in by_kind.most_common():
    print(f"    {n:6d}  {k}")
if blocks:
    print("  by kind, kernel and source line:")
    for (k, kern, at), n in by_site.most_common(20):
        print(f"    {n:6d}  {k}  {kern}  {at}")
    print("  first findings, verbatim:")
    for b in blocks[:3]:
        print("    | " + "\n    | ".join(ln.rstrip() for ln in b if ln.strip()))
sys.exit(1 if blocks else 0)
EOF
}

echo "oclgrind_check: oclgrind $version ($icd), logs in $dir"

# 1. Canary: the checks must see a known race and a known out-of-bounds write.
if ! OCLGRIND_LOG="$canary_prefix" "$py" scripts/oclgrind_check.py --canary > "$dir/canary.out" 2>&1; then
  cat "$dir/canary.out" >&2
  echo "oclgrind_check: FAILED: the canary did not run" >&2; exit 1
fi
for f in "$canary_prefix".canary "$canary_prefix".canary2; do
  if ! grep -q 'data race' "$f" 2>/dev/null || ! grep -q '^Invalid write' "$f" 2>/dev/null; then
    echo "oclgrind_check: FAILED: oclgrind did not report the canary's race and invalid write" \
         "in $f: its checks or its logs are not working" >&2
    exit 1
  fi
done
echo "oclgrind_check: canary reported as expected in both contexts' logs"

# 2. Every kernel.
status=0
timeout "${OCLGRIND_CHECK_TIMEOUT:-900}" env OCLGRIND_LOG="$log" "$py" scripts/oclgrind_check.py "$@" \
  2>&1 | tee "$dir/check.out" || status=$?
shopt -s nullglob
logs=("$log".*)
echo "oclgrind_check: oclgrind log summary (${logs[*]:-no log written}):"
findings=0
if [ ${#logs[@]} -eq 0 ]; then
  echo "oclgrind_check: no oclgrind log was written" >&2; findings=1
else
  summarise "${logs[@]}" || findings=1
fi
elapsed=$(( $(date +%s) - start ))
if [ "$status" -ne 0 ] || [ "$findings" -ne 0 ]; then
  [ "$status" -eq 0 ] || echo "oclgrind_check: the check script failed (exit $status)" >&2
  [ "$findings" -eq 0 ] || echo "oclgrind_check: oclgrind reported findings (see above and $log.*)" >&2
  echo "oclgrind_check: FAILED in ${elapsed} s" >&2
  exit 1
fi
echo "oclgrind_check: PASSED in ${elapsed} s: no oclgrind findings, every comparison passed"
