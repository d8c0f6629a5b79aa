"""The same inputs on the same device give bit-identical outputs, run after run: every kernel
is gather-style (a work item owns what it writes, sums in a fixed order, no float atomics) and
the noise is counter-based. Across chunk sizes: see test_chunking.py."""
import numpy as np

import nlos_cl as nl


def test_every_stage_is_bit_identical_across_runs(device_runtime):
    scene = nl.paper_scene(facet_size_m=0.03)
    axis = nl.TimeAxis(2 * 20 / nl.SPEED_OF_LIGHT + 28e-9, 5e-12, 1800)
    grid = nl.Grid.from_ranges(x=(3.0, 5.0), y=(1.0, 3.0), step_m=0.01)
    runs = []
    for _ in range(3):
        sim = nl.simulate(scene, axis, backend=device_runtime)
        noisy = nl.add_noise(sim, 10.0, seed=4)
        filtered = nl.gauss_filter(noisy)
        loc = nl.locate(filtered, grid, return_map=True, estimator="paper")
        runs.append((sim.histograms().data, noisy.histograms().data,
                     filtered.histograms().data, loc.score_map, loc.position))
    for later in runs[1:]:
        for a, b in zip(runs[0], later):
            assert np.array_equal(a, b)
