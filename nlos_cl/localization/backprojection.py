"""A textbook reference: the brightest voxel of a plain confocal backprojection (the raw record
summed along each voxel's round-trip path). It shares no nlos_cl kernel, so the measured-data
checks (`nlos-cl reproduce real`, tests/realdata) hold the located depth against it."""
from __future__ import annotations

import numpy as np


def backprojection_peak(h, step_m, every, half_width_m, depth_m) -> np.ndarray:
    """The brightest voxel (ours: x, depth y, z) of a plain confocal backprojection: the raw
    record summed at path 2 |voxel - spot| over every `every`-th scan point. A textbook
    reconstruction."""
    axis = h.path_axis()
    g = np.arange(-half_width_m, half_width_m + 1e-9, step_m)
    cells = np.stack(np.meshgrid(g, np.arange(*depth_m, step_m), g, indexing="ij"), -1)
    cells = cells.reshape(-1, 3)
    total = np.zeros(len(cells))
    for d in range(0, h.n_detectors, every):
        u = np.round((2 * np.linalg.norm(cells - h.detector_spots[d], axis=1)
                      - axis.centre0_m[d]) / axis.step_m[d]).astype(int)
        inside = (u >= 0) & (u < h.time_axis.n_bins)
        total[inside] += h.data[d, u[inside]]
    return cells[np.argmax(total)]
