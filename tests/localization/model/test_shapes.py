"""The model's typed seams: every shape satisfies the Shape protocol (names, bounds, steps and
scales of one length, centre first and yaw where YAW says), and a fit's typed result says
the same as its JSON view and the target it belongs to."""
import warnings

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.localization.model.shapes import plate
from nlos_cl.localization.model.shapes.shape import MEMBERS, MODELS, SHAPES, name_of


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_every_shape_satisfies_the_protocol(name):
    shape = SHAPES[name]
    assert all(hasattr(shape, m) for m in MEMBERS)
    n = shape.N_PARAMS
    assert len(shape.NAMES) == n and shape.NAMES[:3] == ("x", "y", "z")
    assert shape.NAMES[shape.YAW] == "yaw"
    for member in ("LOWER", "UPPER", "STEPS", "X_SCALE"):
        assert np.shape(getattr(shape, member)) == (n,), member
    assert np.all(np.asarray(shape.LOWER) < np.asarray(shape.UPPER))
    assert name_of(shape) == name and MODELS[name] == f"upright {name}"


def test_plate_indices_name_the_row():
    row = np.arange(plate.N_PARAMS, dtype=float)
    assert [plate.NAMES[i] for i in (plate.X, plate.WIDTH, plate.HEIGHT, plate.YAW)] == \
        ["x", "width", "height", "yaw"]
    assert plate.extent(row).tolist() == [row[plate.WIDTH], row[plate.HEIGHT], 0.0]


def test_a_model_fit_is_typed_and_its_json_view_agrees(runtime):
    """The paper's scene (collinear spots: height held) fitted with the model estimator."""
    scene = nl.paper_scene(facet_size_m=0.03)
    clean = nl.simulate(scene, nl.default_time_axis(scene.setup, 1e-11), backend=runtime)
    noisy = nl.add_noise(clean, 20.0, seed=3)
    grid = nl.Grid.from_ranges(x=(3.0, 5.0), y=(1.0, 3.0), step_m=0.02)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the height warning
        loc = nl.locate(nl.gauss_filter(noisy), grid, estimator="model", raw=noisy)
    target = loc.targets[0]
    fit = target.fit
    assert fit.shape == "plate" and fit.model == "upright plate"
    assert [p.name for p in fit.parameters] == list(plate.NAMES)
    assert np.allclose(fit.values()[:3], target.position)
    assert not fit["z"].vary and fit["x"].vary and fit["x"].sd > 0  # collinear spots: z held
    assert fit["width"].lower == plate.LOWER[plate.WIDTH]
    assert 0.5 < fit.birge_ratio < 2.0  # a plate explains the plate's data
    assert target.details == fit.as_dict()
    assert list(target.details["params"]) == list(plate.NAMES)
    assert target.details["birge_ratio"] == fit.birge_ratio
