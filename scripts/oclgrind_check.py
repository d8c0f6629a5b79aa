"""Run every registered operation on its tiny examples, for the oclgrind OpenCL simulator.

Meant to run under oclgrind; scripts/oclgrind_check.sh sets the environment (only the
"Oclgrind Simulator" device visible, data-race detection on, OCLGRIND_LOG) and reads the logs.
oclgrind checks every memory access for out-of-bounds reads and writes and every pair of
accesses for data races; it reports into its log and never changes an exit status. This script
walks the operation registry (nlos_cl/ops): each operation's `examples("tiny")` are chosen to
reach every branch that decides an address (partial last blocks, paths outside the record,
chunked groups and slabs), and each result is compared with the float64 NumPy twin within the
example's own tolerance, so that the run means something (a kernel that silently wrote nothing
would pass oclgrind's checks). Then the benchmark's probe kernels. It fails if a kernel of
kernels/*.cl was never launched, or if anything issued a warning (e.g. a compiler note).

oclgrind opens OCLGRIND_LOG afresh for every OpenCL context, so this script gives each
Runtime (each its own context) its own log: OCLGRIND_LOG + "." + a label.

Exit status: 0 if every comparison passed, 1 otherwise (oclgrind's findings are only in the
logs), 2 if the device is not oclgrind.

Usage: python scripts/oclgrind_check.py [--canary] [--device SPEC]
  default: the oclgrind device;
  --canary: only run a kernel with a known race and out-of-bounds write (in two contexts);
  --device: any other device, e.g. --device 0:0 for a quick native run.
"""
from __future__ import annotations

import argparse
import os
import re
import sys
import time
import warnings
from pathlib import Path

import numpy as np


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default=None,
                        help="device spec (default: the oclgrind device, required)")
    parser.add_argument("--canary", action="store_true",
                        help="only run a kernel with a known race and out-of-bounds write")
    return parser.parse_args(argv)


ARGS = parse_args() if __name__ == "__main__" else parse_args([])
# Build every program afresh, so that oclgrind's compiler messages are what this run sees.
os.environ.setdefault("PYOPENCL_NO_CACHE", "1")

from nlos_cl.ops.backend import NumpyBackend  # noqa: E402  (after the environment above is set)
from nlos_cl.ops import OPERATIONS  # noqa: E402
from nlos_cl.ops.base import run_example  # noqa: E402
from nlos_cl.ops.opencl_backend import OpenCLBackend as Runtime  # noqa: E402

KERNELS_DIR = Path(__file__).resolve().parent.parent / "kernels"
FAILURES: list[str] = []
# oclgrind opens (and truncates) OCLGRIND_LOG once per OpenCL context, each with its own file
# position, so a second context overwrites what the first logged. Every Runtime (a context of
# its own) therefore gets its own file, OCLGRIND_LOG + "." + label; the wrapper reads them all.
LOG_BASE = os.environ.get("OCLGRIND_LOG")
RUNTIMES: list = []


def check(ok, what: str, detail: str = "") -> None:
    ok = bool(ok)
    print(f"  [{'ok' if ok else 'FAIL'}] {what}{' (' + detail + ')' if detail else ''}",
          flush=True)
    if not ok:
        FAILURES.append(f"{what} {detail}".strip())


def new_runtime(label, *args, **kwargs) -> Runtime:
    if LOG_BASE:
        os.environ["OCLGRIND_LOG"] = f"{LOG_BASE}.{label}"
    try:
        runtime = Runtime(*args, **kwargs)
    finally:
        if LOG_BASE:
            os.environ["OCLGRIND_LOG"] = LOG_BASE
    RUNTIMES.append(runtime)
    return runtime


def operations(rt) -> None:
    """Every registered operation on its tiny examples, against its twin."""
    twin = NumpyBackend()
    for op in OPERATIONS.values():
        print(f"== {op.name} (kernels/{op.kernel_file}.cl)", flush=True)
        start = time.perf_counter()
        for i, example in enumerate(op.examples("tiny")):
            device = rt
            if example.max_alloc_bytes:  # the chunked path: a capped runtime, its own log
                device = new_runtime(f"{op.name}{i}", rt.device,
                                     max_alloc_bytes=example.max_alloc_bytes)
            error = example.error(run_example(op, example, device),
                                  run_example(op, example, twin))
            check(error <= example.tolerance, f"{example.label}: matches the twin",
                  f"error {error:.2e}, tolerance {example.tolerance:.0e}")
        print(f"   {time.perf_counter() - start:.1f} s", flush=True)


def probes(rt) -> None:
    """probes.cl (the benchmark's limit probes) with a tiny ITERS, against NumPy."""
    print("== probes (kernels/probes.cl)", flush=True)
    iters, items, a = 3, 16, 0.5
    out = rt.empty((items,))
    rt.run(rt.kernel("probes", "exp_probe", ITERS=iters), (items,), out, np.float32(a))
    xs = np.stack([a + np.arange(8) * 1e-3 + 0.1 * j for j in range(8)])
    for _ in range(iters):
        xs = np.exp(-xs)
    check(np.allclose(out.get(), xs.sum(), rtol=1e-5), "exp_probe matches NumPy")
    rt.run(rt.kernel("probes", "fma_probe", ITERS=iters), (items,), out, np.float32(a))
    xs = np.stack([np.full(8, a) + j for j in range(12)])
    for _ in range(iters):
        xs = xs * 0.999 + 1e-3
    check(np.allclose(out.get(), xs.sum(), rtol=1e-5), "fma_probe matches NumPy")
    src = np.random.default_rng(2).random((items, 4)).astype(np.float32)
    dst = rt.empty((items, 4))
    rt.run(rt.kernel("probes", "copy_probe"), (items,), rt.from_numpy(src), dst)
    check(np.array_equal(dst.get(), src), "copy_probe copies")


def all_kernels() -> set:
    """(source, kernel name) of every __kernel in the checkout's kernels/*.cl."""
    found = set()
    for path in sorted(KERNELS_DIR.glob("*.cl")):
        text = re.sub(r"//[^\n]*|/\*.*?\*/", "", path.read_text(), flags=re.S)
        found |= {(path.stem, m) for m in re.findall(r"__kernel\s+void\s+(\w+)", text)}
    return found

CANARY = r"""
__kernel void canary(__global float *out, const int n)
{
    const int i = get_global_id(0);
    out[0] = (float)i;     // every work item writes out[0], each a different value: a data race
    out[n + i] = 1.0f;     // past the end of the n-float buffer: an invalid write
}
"""


def canary(rt) -> int:
    """Run a kernel with a known data race and a known out-of-bounds write, in this context
    and in a second one, so that the wrapper can confirm that oclgrind's checks are on and
    that every context's findings reach their own log."""
    from nlos_cl.device.runtime import cl
    for runtime in (rt, new_runtime("canary2", rt.device)):
        program = cl.Program(runtime.context, CANARY).build()
        out = runtime.empty((4,))
        runtime.run(program.canary, (4,), out, np.int32(4))
        runtime.finish()
    print("oclgrind_check: canary ran (each log must show an invalid write and a data race)")
    return 0


def main() -> int:
    args = ARGS
    start = time.perf_counter()
    rt = new_runtime("canary" if args.canary else "main", args.device or "oclgrind")
    print(f"device: {rt.name}")
    if LOG_BASE:
        print(f"oclgrind logs: {LOG_BASE}.<context> (one per OpenCL context)")
    if args.device is None and "oclgrind" not in rt.name.lower():
        print("oclgrind_check: not running on oclgrind; run scripts/oclgrind_check.sh",
              file=sys.stderr)
        return 2
    if args.canary:
        return canary(rt)
    with warnings.catch_warnings(record=True) as caught:
        # Every warning counts: a compiler note from oclgrind's clang, a cut time window, ...
        warnings.simplefilter("always")
        operations(rt)
        probes(rt)
        for runtime in RUNTIMES:
            runtime.finish()
    print("== coverage")
    for w in caught:
        check(False, "no warning while running", f"{w.category.__name__}: {w.message}")
    ran = set().union(*(runtime.launched for runtime in RUNTIMES))
    missing = sorted(all_kernels() - ran)
    check(not missing, f"every kernel of kernels/*.cl ran ({len(ran)} kernels)",
          "missing: " + ", ".join(f"{s}.cl:{n}" for s, n in missing) if missing else "")
    print(f"oclgrind_check: {len(FAILURES)} failed comparison(s), "
          f"{time.perf_counter() - start:.1f} s")
    for f in FAILURES:
        print(f"  FAIL {f}")
    return 1 if FAILURES else 0


if __name__ == "__main__":
    sys.exit(main())
