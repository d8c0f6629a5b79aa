"""Wall-spot layout generators and the height-observability rule."""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.physics import layouts


def test_the_paper_line_is_a_line():
    spots = layouts.line([-0.5, 0, 0], [-1.5, 0, 0], 3)
    np.testing.assert_allclose(spots, nl.paper_setup().detector_spots)
    assert not layouts.height_observable([0, 0, 0], spots)  # collinear with O


def test_circle_and_patch_geometry():
    c = layouts.circle([-1, 0, 0], 0.5, 8)
    assert c.shape == (8, 3) and np.allclose(c[:, 1], 0)
    np.testing.assert_allclose(np.linalg.norm(c - [-1, 0, 0], axis=1), 0.5)
    assert layouts.height_observable([0, 0, 0], c)
    p = layouts.spad_patch([-1, 0, 0], (32, 32), 0.0375)
    assert p.shape == (1024, 3) and np.allclose(p.mean(axis=0), [-1, 0, 0])
    gaps = np.diff(np.unique(p[:, 0]))
    np.testing.assert_allclose(gaps, 0.0375)
    nl.Setup(detector_spots=p)  # a valid setup: on the wall, no duplicates, none on O


def test_three_non_collinear_spots_see_height():
    spots = [[-0.5, 0, 0], [-1, 0, 0.5], [-1, 0, -0.5]]
    assert layouts.height_observable([0, 0, 0], spots)


@pytest.mark.parametrize("call, field", [
    (lambda: layouts.line([0, 1, 0], [1, 0, 0], 3), "line.start"),
    (lambda: layouts.circle([0, 0, 0], -1, 8), "circle.radius_m"),
    (lambda: layouts.circle([0, 0, 0], 0.5, 0), "circle.count"),
    (lambda: layouts.spad_patch([0, 0, 0], (32, 32), 0.0), "spad_patch.pitch_m"),
])
def test_bad_layouts_name_the_field(call, field):
    with pytest.raises(nl.InputError, match=field):
        call()


def test_spad_patch_counts_must_be_whole_numbers():
    from nlos_cl.physics.layouts import spad_patch
    assert spad_patch((-1.0, 0.0, 0.0), (4.0, 2)).shape == (8, 3)
    with pytest.raises(nl.InputError, match="spad_patch.counts"):
        spad_patch((-1.0, 0.0, 0.0), (2.7, 2.7))
