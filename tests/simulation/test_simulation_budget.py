"""A simulation that would not fit in memory is refused before the work, from an estimate of
its facets, naming facet_size_m and a size that fits (red-team case 36: a 0.4 x 0.4 x 1.6 m box
in 2 mm facets ran ~60 s and 3.8 GB, or was refused for memory only after 21-30 s)."""
import re

import pytest
import trimesh

import nlos_cl as nl
from nlos_cl.apps import cli
from nlos_cl.core.errors import InputError
from nlos_cl.core.limits import MEMORY_LIMIT_ENV
from nlos_cl.physics import meshes

BOX = """setup: {laser_spot: [0, 0, 0], detector_spots: [[-0.5, 0, 0], [-1, 0, 0], [-1.5, 0, 0]]}
targets: [{shape: box, size_m: [0.4, 0.4, 1.6], position: [4, 2, 0]}]
facet_size_m: FACET
time_axis: {dt_s: 10e-12}
"""


def _not_built(*args, **kw):
    raise AssertionError("the mesh was built (or cut) before the budget was checked")


def test_the_red_teams_box_is_refused_before_its_mesh_is_built(tmp_path, monkeypatch, capsys):
    """Under a 1 GiB budget the 2 mm box (2.9 M triangles) is refused by the mesh builder,
    before any triangle exists; the size the message advises is then simulated."""
    monkeypatch.setenv(MEMORY_LIMIT_ENV, "1G")
    scene = tmp_path / "box.yaml"
    scene.write_text(BOX.replace("FACET", "0.002"))
    with monkeypatch.context() as m:
        m.setattr(meshes, "_grid_quad", _not_built)
        m.setattr(trimesh.remesh, "subdivide_to_size", _not_built)
        assert cli.main(["simulate", str(scene), "--out", str(tmp_path / "o.h5")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("nlos-cl: facet_size_m: ")
    assert "box" in err and "set by NLOS_CL_MEMORY_LIMIT" in err
    advised = float(re.search(r"Fix: use facet_size_m >= ([0-9.e-]+)", err).group(1))
    assert 0.002 < advised < 0.01
    # the advice fits: the same box at the advised size passes the check (built, not simulated)
    assert len(meshes.box((0.4, 0.4, 1.6), cell_m=advised).faces) > 0


def test_a_coarse_mesh_cut_too_fine_is_refused_before_it_is_cut(monkeypatch):
    """A mesh of a few large triangles (a file's) is cut by Target.facets: 96 triangles of a
    0.4 x 0.4 x 1.6 m box cut to 2 mm make ~5 M facets, refused before trimesh cuts them."""
    monkeypatch.setenv(MEMORY_LIMIT_ENV, "1G")
    target = nl.Target(meshes.box((0.4, 0.4, 1.6), centre=(4, 2, 0), cell_m=0.5))
    scene = nl.Scene(nl.paper_setup(), target, facet_size_m=0.002)
    monkeypatch.setattr(trimesh.remesh, "subdivide_to_size", _not_built)
    with pytest.raises(InputError, match=r"^facet_size_m: simulating this 2\.88 m\^2 target in "
                       r"0\.002 m facets .* Fix: use facet_size_m >= "):
        nl.simulate(scene)


@pytest.mark.parametrize("build", [
    lambda: meshes.rectangle(0.3, 1.6, cell_m=2e-4),
    lambda: meshes.sphere(0.5, facet_size_m=2e-3),
])
def test_every_builder_counts_its_triangles_first(build, monkeypatch):
    monkeypatch.setenv(MEMORY_LIMIT_ENV, "256M")
    monkeypatch.setattr(meshes, "_grid_quad", _not_built)
    monkeypatch.setattr(trimesh.creation, "icosphere", _not_built)
    with pytest.raises(InputError, match=r"^facet_size_m: simulating a .* Fix: use facet_size_m"):
        build()


def test_the_default_scenes_are_not_refused(monkeypatch):
    """The paper's rectangle at 1 cm and a 0.4 m sphere at 1 cm under a 256 MiB budget."""
    monkeypatch.setenv(MEMORY_LIMIT_ENV, "256M")
    assert nl.paper_scene().facets(0).count > 0
    assert len(meshes.sphere(0.2, facet_size_m=0.01).faces) > 0
