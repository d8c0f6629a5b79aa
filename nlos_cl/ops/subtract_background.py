"""subtract_background (kernels/subtract_background.cl): background removal for frame streams.

subtract_background(frame, background, alpha, clip) -> (frame - background [clipped at 0],
updated background). alpha = 0 keeps a fixed reference (a target-free capture); alpha > 0 makes
the background an exponential running mean of past frames, updated on the device in place (the
returned background is the same buffer). Both arrays are in the same units (the caller scales).
"""
from __future__ import annotations

import numpy as np

from .base import Example, Operation, relative_error


def numpy(frame, background, alpha, clip):
    frame, background = np.asarray(frame, np.float64), np.asarray(background, np.float64)
    diff = frame - background
    return (np.maximum(diff, 0.0) if clip else diff), background + alpha * diff


def opencl(rt, frame, background, alpha, clip, out=None):
    out = out if out is not None else rt.empty(frame.shape)
    rt.run(rt.kernel("subtract_background", "subtract_background", CLIP=int(bool(clip))),
           (frame.size,), frame, background, np.float32(alpha), np.int32(frame.size), out)
    return out, background


def _error(device, twin) -> float:
    return max(relative_error(device[0], twin[0]), relative_error(device[1], twin[1]))


def examples(size):
    rows, n = (2, 37) if size == "tiny" else (3, 4096)
    rng = np.random.default_rng(7)
    frame = rng.random((rows, n)).astype(np.float32)
    background = (0.5 * rng.random((rows, n))).astype(np.float32)
    return [Example(f"{rows} x {n}, {'running mean' if a else 'fixed'}, "
                    f"{'clipped' if clip else 'negatives kept'}",
                    (lambda a, c: lambda be: (be.from_numpy(frame), be.from_numpy(background),
                                              a, c))(a, clip), 1e-6, _error)
            for a, clip in ((0.0, True), (0.05, False))]


OP = Operation("subtract_background", "subtract_background", opencl, numpy, examples,
               tolerance_note="1e-6 of the peak: one float32 subtraction and one FMA per bin.",
               bound="bandwidth")
