"""Target meshes: the paper's rectangle, boxes, spheres, and any mesh file trimesh reads.

trimesh is imported here only, so code that never builds a mesh (locating a capture) never
pays for it.
"""
from __future__ import annotations

import math

import numpy as np
import trimesh

from ..core.errors import require
from ..core.geometry import as_point
from ..core.tuning import FACET_M

# Peak memory of a simulation (PoCL, CPU), refused up front against core.limits' budget:
# FACET_BYTES per facet (Target.facets' cut with its edges refined, the visibility test, the
# forward's buffers; a 0.4 x 0.4 x 1.6 m box of 96 faces cut to 4-6 mm: 0.7-1.0 kB) and
# MESH_FACE_BYTES per triangle of a mesh pre-gridded at the facet size (trimesh's arrays and
# caches; the same box built at 2-5 mm: ~0.4 kB). The box at 3.5-8 mm peaked at 1.3 kB a
# triangle in all (+0.16 GB for OpenCL); at 2 mm it took ~60 s and 3.8 GB before this check.
FACET_BYTES, MESH_FACE_BYTES = 1000.0, 400.0


def require_facets(n_facets: float, what: str, cell: float, mesh_faces: float = 0.0) -> None:
    """Refuse, before building or cutting, a target whose simulation would not fit in the
    memory budget: n_facets facets of `cell` m (plus mesh_faces triangles still to build)."""
    from ..core.limits import memory_limit, require_memory
    need = FACET_BYTES * n_facets + MESH_FACE_BYTES * mesh_faces
    coarser = cell * math.sqrt(max(need / max(memory_limit(), 1), 1.0)) * 1.05
    digit = 10.0 ** (math.floor(math.log10(coarser)) - 1)  # 2 digits, rounded up
    require_memory("facet_size_m", need, f"simulating {what} in {cell:.3g} m facets "
                   f"(~{n_facets:.3g} facets)", f"use facet_size_m >= "
                   f"{math.ceil(coarser / digit - 1e-9) * digit:.2g} "
                   "(1 cm is the default and converges)")


def _cells(u_len: float, v_len: float, cell: float) -> tuple[int, int]:
    """Grid cells along u and v of a face cut into right triangles of longest edge `cell`."""
    require(math.isfinite(cell) and cell > 0, "facet_size_m", f"must be a positive length in "
            f"metres, got {cell!r}", "pass e.g. 0.01")
    side = cell / math.sqrt(2.0)
    return max(1, math.ceil(u_len / side - 1e-9)), max(1, math.ceil(v_len / side - 1e-9))


def _grid_quad(u_len: float, v_len: float, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """A u_len x v_len rectangle in the (u, v) plane as a grid of right triangles whose
    longest edge (the cell diagonal) is at most `cell` (its budget checked by the caller)."""
    nu, nv = _cells(u_len, v_len, cell)
    u = np.linspace(-u_len / 2, u_len / 2, nu + 1)
    v = np.linspace(-v_len / 2, v_len / 2, nv + 1)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    verts = np.stack([uu.ravel(), vv.ravel()], axis=1)
    idx = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return verts, faces


def rectangle(width_m: float = 0.3, height_m: float = 1.6, centre=(4.0, 2.0, 0.0),
              normal=(-1.0, 0.0, 0.0), cell_m: float = 0.01) -> trimesh.Trimesh:
    """An upright one-sided rectangle: `height_m` along z, `width_m` across, facing `normal`.

    The paper's target (Section 3.1) is the default: 0.3 m along y by 1.6 m along z, centred at
    (4, 2, 0) in the plane x = 4, facing the wall side (-x). Pre-gridded at `cell_m` so that no
    further subdivision is needed at that facet size.
    """
    require(width_m > 0 and height_m > 0, "rectangle", "width_m and height_m must be positive",
            "pass sizes in metres")
    n = np.asarray(normal, dtype=np.float64)
    require(n.shape == (3,) and np.linalg.norm(n) > 0 and abs(n[2]) < 1e-9, "rectangle.normal",
            f"must be a horizontal non-zero vector, got {n.tolist()}",
            "pass e.g. (-1, 0, 0); for tilted rectangles rotate the mesh with trimesh")
    n = n / np.linalg.norm(n)
    across = np.cross([0.0, 0.0, 1.0], n)  # horizontal in-plane direction
    up = np.array([0.0, 0.0, 1.0])
    nu, nv = _cells(width_m, height_m, cell_m)
    require_facets(2 * nu * nv, f"a {width_m:.3g} m x {height_m:.3g} m rectangle", cell_m,
                   2 * nu * nv)
    verts2d, faces = _grid_quad(width_m, height_m, cell_m)
    verts = np.asarray(centre, float) + verts2d[:, :1] * across + verts2d[:, 1:] * up
    mesh = trimesh.Trimesh(verts, faces, process=False)
    if np.dot(mesh.face_normals[0], n) < 0:
        mesh.invert()
    return mesh


def box(extents=(0.3, 0.3, 1.6), centre=(4.0, 2.0, 0.0), cell_m: float = 0.01) -> trimesh.Trimesh:
    """A closed box, each side pre-gridded at `cell_m`, outward normals."""
    ext = np.asarray(extents, dtype=np.float64)
    require(ext.shape == (3,) and bool(np.all(ext > 0)), "box.extents",
            f"must be three positive lengths, got {ext.tolist()}", "pass e.g. (0.3, 0.3, 1.6)")
    faces = 4 * sum(math.prod(_cells(*np.delete(ext, axis), cell_m)) for axis in range(3))
    require_facets(faces, f"a {' x '.join(f'{v:.3g}' for v in ext)} m box", cell_m, faces)
    parts = []
    for axis in range(3):
        u_ax, v_ax = [a for a in range(3) if a != axis]
        verts2d, faces = _grid_quad(ext[u_ax], ext[v_ax], cell_m)
        for sign in (-1.0, 1.0):
            verts = np.zeros((len(verts2d), 3))
            verts[:, u_ax], verts[:, v_ax] = verts2d[:, 0], verts2d[:, 1]
            verts[:, axis] = sign * ext[axis] / 2
            m = trimesh.Trimesh(verts + np.asarray(centre, float), faces, process=False)
            if m.face_normals[0][axis] * sign < 0:
                m.invert()
            parts.append(m)
    return trimesh.util.concatenate(parts)


# an icosphere's longest edge / radius at level 0; projecting the midpoints onto the sphere
# stretches the longest edges of level k to ~1.2 x this / 2^k: 1.25 bounds them
ICOSAHEDRON_EDGE = 1.25 * 4.0 / math.sqrt(10.0 + 2.0 * math.sqrt(5.0))
MAX_SPHERE_LEVEL = 9  # 5.2 M faces


def sphere_level(radius_m: float, facet_size_m: float) -> int:
    """The icosphere subdivision level whose longest edge is at most `facet_size_m`: its chord
    error (sagitta, the flat faces' distance below the sphere) is then at most
    facet_size_m^2 / (8 radius_m) (1 cm facets on a 0.2 m sphere: 0.06 mm)."""
    level = math.ceil(math.log2(max(ICOSAHEDRON_EDGE * radius_m / facet_size_m, 1.0)) - 1e-9)
    require(level <= MAX_SPHERE_LEVEL, "sphere.facet_size_m", f"{facet_size_m:.3g} m facets on "
            f"a {radius_m:.3g} m sphere need subdivision level {level}",
            f"use facet_size_m >= {ICOSAHEDRON_EDGE * radius_m / 2 ** MAX_SPHERE_LEVEL:.2g}")
    return max(level, 0)


def sphere(radius_m: float = 0.2, centre=(4.0, 2.0, 0.0), subdivisions: int | None = None,
           facet_size_m: float = FACET_M) -> trimesh.Trimesh:
    """An icosphere whose edges are at most `facet_size_m` (vertices on the sphere, so the
    chord error is bounded: see `sphere_level`); `subdivisions` fixes the level instead."""
    require(radius_m > 0, "sphere.radius_m", f"must be positive, got {radius_m}", "pass metres")
    require(math.isfinite(facet_size_m) and facet_size_m > 0, "sphere.facet_size_m",
            f"must be a positive length in metres, got {facet_size_m!r}", "pass e.g. 0.01")
    level = sphere_level(radius_m, facet_size_m) if subdivisions is None else int(subdivisions)
    faces = 20 * 4 ** level  # an icosphere's triangles; its edges need no further cut
    require_facets(faces, f"a {radius_m:.3g} m sphere", facet_size_m, faces)
    mesh = trimesh.creation.icosphere(subdivisions=level, radius=radius_m)
    mesh.apply_translation(np.asarray(centre, float))
    return mesh


def l_block(size_m=(0.6, 0.4, 0.6), notch_m=(0.3, 0.3), centre=(2.0, 2.0, 0.0)
            ) -> trimesh.Trimesh:
    """A concave L-shaped block: a box of `size_m` with a `notch_m` (x, y) corner cut away
    over its full height (the notch at +x, -y: it opens towards the wall side), closed and
    outward-facing (20 triangles: Target.facets cuts it); the test shape for self-occlusion."""
    sx, sy, sz = (float(v) for v in size_m)
    nx, ny = (float(v) for v in notch_m)
    require(0 < nx < sx and 0 < ny < sy and sz > 0, "l_block", "the notch must be smaller than "
            "the block", "pass e.g. size_m=(0.6, 0.4, 0.6), notch_m=(0.3, 0.3)")
    c = np.asarray(centre, float)
    ring = np.array([[0, 0], [sx - nx, 0], [sx - nx, ny], [sx, ny], [sx, sy], [0, sy]])
    ring = ring - [sx / 2, sy / 2]
    bottom = np.column_stack([ring, np.full(6, -sz / 2)])
    top = np.column_stack([ring, np.full(6, sz / 2)])
    cap = np.array([[0, 1, 2], [0, 2, 5], [2, 3, 4], [2, 4, 5]])  # the L, counter-clockwise
    sides = [[i, (i + 1) % 6, 6 + (i + 1) % 6] for i in range(6)]
    sides += [[i, 6 + (i + 1) % 6, 6 + i] for i in range(6)]
    faces = np.concatenate([cap[:, ::-1], cap + 6, np.array(sides)])
    return trimesh.Trimesh(np.concatenate([bottom, top]) + c, faces, process=True)


def load_mesh(path, *, position=None) -> trimesh.Trimesh:
    """Load a mesh file (OBJ, STL, PLY, OFF, GLB, glTF; plain, compressed or in an archive)
    through the input gate (nlos_cl.physics.mesh_files: sizes budgeted, regular files only,
    a truncated file refused), optionally re-centred at `position` (its bounding-box centre
    moves there)."""
    from .mesh_files import read_mesh
    loaded = read_mesh(path)
    if position is not None:
        loaded.apply_translation(as_point(position, "position") - loaded.bounds.mean(axis=0))
    return loaded
