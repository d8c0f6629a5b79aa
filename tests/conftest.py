import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.reference import NumpyBackend
from nlos_cl.runtime import get_runtime

C = nl.SPEED_OF_LIGHT


@pytest.fixture(scope="session")
def runtime():
    return get_runtime()


@pytest.fixture(scope="session")
def reference():
    return NumpyBackend()


def window_around(setup, target_mesh, dt_s, margin_m=0.5):
    """A time axis covering every hidden path the target can produce, plus a margin."""
    pts = target_mesh.vertices
    r1 = np.linalg.norm(pts - setup.laser_spot, axis=1)
    paths = r1[None, :] + np.linalg.norm(pts[None] - setup.detector_spots[:, None], axis=2)
    lo, hi = paths.min() - margin_m, paths.max() + margin_m
    t0 = (2 * setup.device_distance_m + lo) / C + setup.pulse.peak_delay_s
    return nl.TimeAxis(t0, dt_s, int(np.ceil((hi - lo) / (C * dt_s))))


def facing_rectangle(position, size=0.3, cell=0.01):
    """A square target at `position` turned towards the middle of the paper's wall spots."""
    p = np.asarray(position, float)
    normal = np.array([-0.75, 0.0, 0.0]) - p
    normal[2] = 0.0
    return nl.rectangle(size, size, centre=p, normal=normal, cell_m=cell)
