"""The paper's argmax's frame-to-frame scatter, measured on the data (tracking/scatter.py): the
sigma a tracker gives measurements without covariance."""
import math

import numpy as np

import nlos_cl as nl
from nlos_cl.tracking.scatter import argmax_scatter, robust_sigma

GRID = nl.Grid.from_ranges(x=(2.5, 5.5), y=(0.5, 3.5), step_m=0.01)


def test_the_scatter_of_a_still_target_is_its_argmax_noise():
    clean = nl.simulate(nl.paper_scene())
    frames = [nl.add_noise(clean, -10, seed=s).histograms() for s in range(12)]
    sigma = argmax_scatter(frames, GRID, h_s=0.65e-9, floor=0.0)
    positions = np.array([nl.locate(nl.gauss_filter(h), GRID, estimator="paper").position
                          for h in frames])
    direct = float(np.max(np.std(positions, axis=0)))
    assert 0.4 * direct < sigma < 2.5 * direct  # 12 frames: a rough but honest estimate


def test_few_frames_or_a_quiet_target_keep_the_floor():
    clean = nl.simulate(nl.paper_scene())
    frames = [nl.add_noise(clean, 10, seed=s).histograms() for s in range(8)]
    assert argmax_scatter(frames[:4], GRID, h_s=0.65e-9, floor=0.05) == 0.05
    assert argmax_scatter(frames, GRID, h_s=0.65e-9, floor=0.05) == 0.05  # 10 dB: ~1 cm


def test_the_scatter_reads_through_heavy_tails():
    """Second differences of 0.1 m errors (sd sqrt(6) x 0.1), 15 % replaced by metre-sized
    jumps: the pooled robust sigma stays near 0.1 where the standard deviation would not."""
    rng = np.random.default_rng(4)
    second = math.sqrt(6) * 0.1 * rng.standard_normal((400, 3))
    wrong = rng.random(400) < 0.15
    second[wrong] = rng.uniform(-3, 3, (wrong.sum(), 3))
    assert 0.09 < robust_sigma(second, 0.0) < 0.13
    assert float(np.max(second.std(axis=0))) / math.sqrt(6) > 0.25
