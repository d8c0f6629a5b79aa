"""The stream bench's frames (`nlos-cl bench`'s stream rows and the tests that replay them): the
paper's scene at 10 ps x 4,096 bins, simulated once, and noisy copies of it at 10 dB (seeded),
cycled by the bench so that the noise draws are not what is timed."""
from __future__ import annotations

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.paths import TimeAxis
from ..physics.scene import paper_scene
from .frame import simulate


def stream_frames(backend, n_copies: int = 8, snr_db: float = 10.0, seed: int = 0):
    """(clean HistogramSet, [n_copies noisy ones]): white Gaussian noise `snr_db` below each
    histogram's mean power, from default_rng(seed)."""
    clean = simulate(paper_scene(facet_size_m=0.02), TimeAxis(40 / SPEED_OF_LIGHT, 10e-12, 4096),
                     backend=backend).histograms()
    rng = np.random.default_rng(seed)
    power = np.sqrt(np.mean(clean.data ** 2, axis=1, keepdims=True) / 10.0 ** (snr_db / 10.0))
    return clean, [clean.with_data(clean.data + power * rng.standard_normal(clean.data.shape))
                   for _ in range(n_copies)]
