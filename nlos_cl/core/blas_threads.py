"""The host model's BLAS calls run on one thread (`serial_blas`, around each model estimate).

Why: the model fit's NumPy work is thousands of small products (a plate's column against the
Newton weights, (1, 64 x 319) @ (64 x 319, 1); normal equations of a few columns), each
microseconds of arithmetic. OpenBLAS splits such calls over all its threads and then spins
them: on this 2-core machine with another process on the second core, that matrix product took
85 us on its threads against 8 us on one, the Poisson Newton's iteration 250 us against ~60,
and CC-SOCR's 4,096 histograms read as one laser located in 9.6 / 11.0 s against 7.5 / 6.9 s
(interleaved, the same answers). Nothing in a fit is large enough for the threads to pay back
their synchronisation; PoCL's own threads (the kernels) also lose the core they spin on.

Settings the user made win: nothing is limited where OPENBLAS_NUM_THREADS, OMP_NUM_THREADS or
MKL_NUM_THREADS is in the environment, or NLOS_CL_SERIAL_BLAS=0. The limit is process-wide
while it holds (BLAS libraries keep one setting), and restored on exit: a user's own NumPy
running in another thread during a fit gets one BLAS thread meanwhile.
"""
from __future__ import annotations

import contextlib
import os

USER_SETTINGS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")

_controller = None  # threadpoolctl's view of the loaded BLAS libraries, made at first use


def _wanted() -> bool:
    return os.environ.get("NLOS_CL_SERIAL_BLAS", "1") != "0" and \
        not any(name in os.environ for name in USER_SETTINGS)


def serial_blas():
    """A context in which the loaded BLAS libraries use one thread (see the module's
    docstring); a no-op where the user set the threads. Entering and leaving costs ~7 us (the
    libraries are listed once, ~0.7 ms, at the first call)."""
    global _controller
    if not _wanted():
        return contextlib.nullcontext()
    if _controller is None:
        from threadpoolctl import ThreadpoolController
        _controller = ThreadpoolController()
    return _controller.limit(limits=1, user_api="blas")
