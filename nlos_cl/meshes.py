"""Target meshes: the paper's rectangle, boxes, spheres, and any mesh file trimesh reads.

trimesh is imported here only, so code that never builds a mesh (locating a capture) never
pays for it.
"""
from __future__ import annotations

import math

import numpy as np
import trimesh

from .errors import InputError, require
from .geometry import as_point


def _grid_quad(u_len: float, v_len: float, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """A u_len x v_len rectangle in the (u, v) plane as a grid of right triangles whose
    longest edge (the cell diagonal) is at most `cell`."""
    require(math.isfinite(cell) and cell > 0, "facet_size_m", f"must be a positive length in "
            f"metres, got {cell!r}", "pass e.g. 0.01")
    side = cell / math.sqrt(2.0)
    nu, nv = max(1, math.ceil(u_len / side - 1e-9)), max(1, math.ceil(v_len / side - 1e-9))
    from .safe_io import require_memory
    require_memory("facet_size_m", 200.0 * (nu + 1) * (nv + 1), f"a {u_len:.3g} m x {v_len:.3g} "
                   f"m face cut into {cell:.3g} m facets ({2 * nu * nv:.3g} triangles)",
                   f"use facet_size_m >= {math.sqrt(u_len * v_len * 800 / 2**30):.2g} "
                   "(1 cm is the default and converges)")
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


def sphere(radius_m: float = 0.2, centre=(4.0, 2.0, 0.0), subdivisions: int = 4) -> trimesh.Trimesh:
    require(radius_m > 0, "sphere.radius_m", f"must be positive, got {radius_m}", "pass metres")
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius_m)
    mesh.apply_translation(np.asarray(centre, float))
    return mesh


def load_mesh(path, *, position=None) -> trimesh.Trimesh:
    """Load any mesh file trimesh reads (OBJ, STL, PLY, GLB, ...), optionally re-centred at
    `position` (its bounding-box centre moves there)."""
    try:
        loaded = trimesh.load(path, force="mesh")
    except Exception as exc:  # trimesh raises many types for bad files
        raise InputError(f"mesh file {path!s}: could not be read ({exc}). "
                         "Fix: pass a mesh file trimesh can load (OBJ, STL, PLY, GLB, OFF)") from exc
    require(isinstance(loaded, trimesh.Trimesh) and len(loaded.faces) > 0, f"mesh file {path!s}",
            "holds no triangles", "pass a file with a surface mesh")
    if position is not None:
        loaded.apply_translation(as_point(position, "position") - loaded.bounds.mean(axis=0))
    return loaded
