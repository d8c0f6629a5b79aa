"""Every bad input of the catalogue (tests/apps/error_catalogue.py, docs/results/errors/errors.md) gets
an error naming the field and the fix; inputs stay unmodified."""
import numpy as np
import pytest

import nlos_cl as nl
from error_catalogue import CASES, histograms, message


@pytest.mark.parametrize("what, field, call", CASES, ids=[c[0] for c in CASES])
def test_catalogue_row(what, field, call):
    kind, text = message(call)
    assert kind, f"{what}: no error was raised"
    assert field in text, text
    assert "Fix:" in text or "Install" in text, text


def test_catalogue_has_at_least_20_rows():
    assert len(CASES) >= 20


def test_inputs_are_not_modified():
    data = np.ones((3, 100))
    spots = nl.paper_setup().detector_spots.copy()
    hist = histograms(data)
    data[0, 0] = 7.0  # the set holds its own copy
    assert hist.data[0, 0] == 1.0
    assert not hist.data.flags.writeable
    mesh = nl.rectangle()
    vertices = mesh.vertices.copy()
    target = nl.Target(mesh)
    mesh.apply_translation([1, 0, 0])  # later edits to the caller's mesh do not leak in
    assert np.array_equal(target.mesh.vertices, vertices)
    nl.gauss_filter(hist, backend="reference")
    assert np.array_equal(nl.paper_setup().detector_spots, spots)
