"""The plates' lattice: how many cells across and up a plate (and each face of a box) is cut
into, and how its cells' points share their spread of paths with the pulse blur
(plate.Lattice). Filtered data: GAUSS_LATTICE and plate.BLUR_SHARE; photon counts, whose
model pulse is ~5x narrower: `counts_lattice`, scaled with that pulse, and
plate.COUNTS_BLUR_SHARE."""
from __future__ import annotations

import math

import numpy as np

from ....core.constants import TINY
from . import box, plate

# Plate lattices (cells across x up). 16 x 24 for filtered AWGN data: a noise-free fit of
# 1 cm-facet data from the truth is then off by <= 0.25 sd (Mahalanobis) on the
# 0.3 x 1.6 m plate, a 0.7 m and a 1 m square (10 x 20 left the 0.7 m square 1 sd off).
GAUSS_LATTICE = (16, 24)
# Photon counts are not Gauss-filtered: the model's pulse is the laser's and the jitter alone
# (sigma0 ~1.27 cm of path at 70 ps FWHM and 30 ps), and a cell spanning a few of those combs
# (tests/localization/model/test_model_cell_comb.py): on 16 x 32 a 1.2 m plate seen obliquely was modelled 19 %
# off, and counts draw 46's true plate cost 5,510 deviance units against 3,783 converged, so a
# cylinder 0.5 m off fitted better. POISSON_LATTICE keeps every case of that test within
# 1.6 % at that pulse (32 x 30: 960 cells, under ops.plate_model's 1,016, which the paired
# layouts need), with the cells' points at plate.COUNTS_BLUR_SHARE; the cells scale with the
# pulse (`counts_lattice`), so a narrower one gets finer cells and a wider one coarser,
# within COUNTS_SCALE.
POISSON_LATTICE, POISSON_SIGMA_M = (32, 30), 0.0127
COUNTS_SCALE = (0.5, 2.0)


def counts_lattice(obs):
    """A counts observation's plate lattice (nu, nv): POISSON_LATTICE scaled by POISSON_SIGMA_M
    over its model pulse (obs.sigma0_m), within COUNTS_SCALE; a layout with a laser spot per
    detector (only ops.plate_model models it) at most that operation's MAX_CELLS."""
    from ....ops.plate_model import MAX_CELLS
    scale = min(max(POISSON_SIGMA_M / max(obs.sigma0_m, TINY), COUNTS_SCALE[0]),
                COUNTS_SCALE[1])
    nu, nv = (max(1, round(n * scale)) for n in POISSON_LATTICE)
    if np.ndim(obs.laser) == 2 and nu * nv > MAX_CELLS:
        shrink = math.sqrt(MAX_CELLS / (nu * nv))
        nu, nv = int(nu * shrink), int(nv * shrink)
    return nu, nv


def lattice_for(obs, lattice=None):
    """The lattice a fit of `obs` uses: `lattice` (a user's (nu, nv)) or GAUSS_LATTICE for
    filtered data; `lattice` or `counts_lattice` for counts, as a plate.Lattice whose flat
    cells take plate.COUNTS_BLUR_SHARE."""
    if obs.mode == "gauss":
        return lattice or GAUSS_LATTICE
    nu, nv = lattice or counts_lattice(obs)
    return plate.Lattice(nu, nv, plate.COUNTS_BLUR_SHARE, counts_depth_cells(nu))


def counts_depth_cells(nu) -> int:
    """A box's cells along its depth for counts on nu cells across: box.DEPTH_CELLS (8) at the
    filtered lattice's 16 across, as many per cell across beyond it (16 at 32 across): on 8,
    a 0.6 m-deep box seen side-on was modelled 2.6 % off at counts' pulse (16: 0.3 %;
    tests/localization/model/test_model_cell_comb.py)."""
    return max(box.DEPTH_CELLS, -(-box.DEPTH_CELLS * int(nu) // GAUSS_LATTICE[0]))
