"""Scenes with several targets: third-order light, so their signals add; truths per target."""
import numpy as np
import pytest

import nlos_cl as nl

C = nl.SPEED_OF_LIGHT


@pytest.mark.parametrize("backend", ["reference", None], ids=["twin", "opencl"])
def test_two_targets_signals_add_with_their_own_reflectance(backend):
    setup = nl.paper_setup()
    a = nl.Target(nl.rectangle(0.3, 0.3, centre=(4, 2, 0)))
    b = nl.Target(nl.rectangle(0.3, 0.3, centre=(2, 4, 0)), brdf=0.3)  # its own BRDF
    axis = nl.TimeAxis(40 / C, 10e-12, 4096)
    both = nl.simulate(nl.Scene(setup, a, 0.02, more_targets=(b,)), axis, backend=backend)
    alone = [nl.simulate(nl.Scene(setup, t, 0.02), axis, backend=backend).histograms().data
             for t in (a, b)]
    data = both.histograms().data
    assert np.abs(data - (alone[0] + alone[1])).max() < 1e-6 * data.max()  # float32 sum
    np.testing.assert_array_equal(both.histograms().truths, [[4, 2, 0], [2, 4, 0]])
    assert np.array_equal(both.layout.truth, [4, 2, 0])


def test_a_more_target_that_is_not_a_target_is_named():
    with pytest.raises(nl.InputError, match=r"scene.more_targets\[0\]"):
        nl.Scene(nl.paper_setup(), nl.Target(nl.rectangle()), more_targets=("box.obj",))
