"""An example runner (docs/sweeps.md, "A study of your own function"): the paper's target at
(x, y), white noise at `snr_db`, the Gauss filter and the paper's argmax. The clean simulation
is kept per worker process (`worker_cache`), so the seeds of one position simulate it once.

    runner: "nlos_cl.sweep.examples:paper_target"
    axes: [{name: x, values: [3, 4]}, {name: snr_db, values: [0, 10]}]
    seeds: 3
"""
from __future__ import annotations

from .registry import runner
from .runner import worker_cache


@worker_cache(keep=3)
def clean(x: float, y: float, facet_m: float, dt_s: float):
    """The noiseless signals of the paper's 0.3 x 1.6 m rectangle centred at (x, y, 0)."""
    from ..core.paths import default_time_axis
    from ..physics.meshes import rectangle
    from ..physics.scene import Scene, Target, paper_setup
    from ..simulation.frame import simulate
    mesh = rectangle(0.3, 1.6, centre=(x, y, 0.0), normal=(-1.0, 0.0, 0.0), cell_m=facet_m)
    scene = Scene(paper_setup(), Target(mesh), facet_m, truth=(x, y, 0.0))
    return simulate(scene, default_time_axis(scene.setup, dt_s))


@runner
def paper_target(x: float, seed: int, y: float = 2.0, snr_db: float = 10.0,
                 facet_m: float = 0.02, dt_s: float = 1e-11, step_m: float = 0.02) -> dict:
    """One run: {'position': [x, y, z] located, 'error_m': distance to the truth}."""
    from ..core.grid import Grid
    from ..localization.api import gauss_filter, locate
    from ..simulation.frame import add_noise
    from .values import check_grid
    ranges = {"x": [0.0, 6.0], "y": [0.01, 6.0], "step_m": step_m}
    check_grid(ranges)  # the study's grid's check: a step the search can score
    noisy = add_noise(clean(x, y, facet_m, dt_s), snr_db, seed)
    grid = Grid.from_ranges(**ranges)
    loc = locate(gauss_filter(noisy, 0.65e-9), grid, estimator="paper")
    return {"position": loc.position, "error_m": loc.error_m}
