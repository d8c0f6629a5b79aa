"""Self-occlusion and mutual shadowing: which facets see the laser spot and each detector spot.

A facet contributes to detector d only if the segment from its centre to the laser spot O and
the segment from its centre to d's spot both miss every triangle of the scene (every target,
itself included). All targets lie in y > 0 and the spots on the wall y = 0, so a ray from a
facet towards a spot can only hit a triangle before it reaches the wall: an any-hit test of the
half-line is the segment test.

The ray caster is trimesh's Embree binding where `embreex` is installed, else a vectorised
NumPy one (triangles in Morton-ordered clusters of CLUSTER with bounding boxes, Moller-Trumbore
on the clusters a ray's box test lets through); `any_hit_brute` tests every triangle (the
twin of both, for the tests). Work is saved where geometry settles the answer: a planar
target or a closed convex one cannot shadow itself (a ray leaving a convex surface on its
front side never re-enters it), and as an occluder of other targets a closed convex target is
replaced by its convex hull (the same solid, a dozen triangles for a box).

Visibility is computed once per scene and cached there (`Scene.visibility`); the forward
operation takes it as a (detectors, facets) mask.
"""
from __future__ import annotations

import numpy as np

from ..core.constants import TINY
from ..core.geometry import morton_order

CLUSTER = 32  # triangles per bounding box in the NumPy caster
RAY_BLOCK = 2048  # rays per slab test block
PAIR_BLOCK = 8192  # (ray, cluster) pairs per Moller-Trumbore block
OFFSET_M = 1e-6  # ray origins sit this far in front of their facet (float64 casting)
T_MIN = 1e-9


def moller_trumbore(origins, dirs, tri) -> np.ndarray:
    """Hits of rays (..., 3) with triangles (..., 3, 3), broadcast: t > T_MIN inside the
    triangle (edges included)."""
    v0 = tri[..., 0, :]
    e1, e2 = tri[..., 1, :] - v0, tri[..., 2, :] - v0
    p = np.cross(dirs, e2)
    det = np.einsum("...k,...k->...", e1, p)
    ok = np.abs(det) > TINY
    inv = 1.0 / np.where(ok, det, 1.0)
    s = origins - v0
    u = np.einsum("...k,...k->...", s, p) * inv
    q = np.cross(s, e1)
    v = np.einsum("...k,...k->...", dirs, q) * inv
    t = np.einsum("...k,...k->...", e2, q) * inv
    return ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > T_MIN)


def any_hit_brute(origins, dirs, triangles) -> np.ndarray:
    """(N,) whether each ray hits any triangle: every ray against every triangle."""
    hit = np.zeros(len(origins), bool)
    step = max(1, 4_000_000 // max(len(triangles), 1))
    for lo in range(0, len(origins), step):
        o, d = origins[lo:lo + step, None], dirs[lo:lo + step, None]
        hit[lo:lo + step] = moller_trumbore(o, d, triangles[None]).any(axis=1)
    return hit


def _clusters(triangles):
    order = morton_order(triangles.mean(axis=1))
    tri = triangles[order]
    n_c = -(-len(tri) // CLUSTER)
    pad = np.repeat(tri[-1:], n_c * CLUSTER - len(tri), axis=0)  # repeats hit like the last
    tri = np.concatenate([tri, pad]).reshape(n_c, CLUSTER, 3, 3)
    return tri, tri.min(axis=(1, 2)), tri.max(axis=(1, 2))


def any_hit_numpy(origins, dirs, triangles) -> np.ndarray:
    """(N,) any-hit by clusters: slab test of each ray against every cluster's box, then the
    clusters' triangles for the (ray, cluster) pairs that pass."""
    tri, lo, hi = _clusters(np.asarray(triangles, np.float64))
    hit = np.zeros(len(origins), bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / dirs
    for r0 in range(0, len(origins), RAY_BLOCK):
        o, iv = origins[r0:r0 + RAY_BLOCK, None], inv[r0:r0 + RAY_BLOCK, None]
        with np.errstate(invalid="ignore"):
            t1, t2 = (lo[None] - o) * iv, (hi[None] - o) * iv
        t_near = np.nan_to_num(np.minimum(t1, t2), nan=-np.inf).max(axis=2)
        t_far = np.nan_to_num(np.maximum(t1, t2), nan=np.inf).min(axis=2)
        rays, cl = np.nonzero((t_near <= t_far) & (t_far > 0))
        for p0 in range(0, len(rays), PAIR_BLOCK):
            r, c = rays[p0:p0 + PAIR_BLOCK] + r0, cl[p0:p0 + PAIR_BLOCK]
            todo = ~hit[r]
            r, c = r[todo], c[todo]
            found = moller_trumbore(origins[r, None], dirs[r, None], tri[c]).any(axis=1)
            hit[r[found]] = True
    return hit


def any_hit(origins, dirs, triangles) -> np.ndarray:
    """Embree through trimesh where embreex is installed, else the NumPy clusters."""
    try:
        import embreex  # noqa: F401
    except ImportError:
        return any_hit_numpy(origins, dirs, triangles)
    import trimesh
    from trimesh.ray.ray_pyembree import RayMeshIntersector
    mesh = trimesh.Trimesh(triangles.reshape(-1, 3), np.arange(triangles.shape[0] * 3)
                           .reshape(-1, 3), process=False)
    # Embree casts in float32: start the rays 0.1 mm off the surface.
    return RayMeshIntersector(mesh).intersects_any(origins + 1e-4 * dirs, dirs)


def _planar(mesh) -> bool:
    normals = mesh.face_normals
    return bool(np.all(normals @ normals[0] > 1 - 1e-9)) and bool(
        np.ptp((mesh.vertices - mesh.vertices[0]) @ normals[0]) < 1e-9)


def _convex_hull(mesh):
    """The mesh's convex hull if the mesh is a closed convex solid, else None."""
    merged = mesh.copy()
    merged.merge_vertices()
    if not merged.is_watertight:
        return None
    hull = merged.convex_hull
    return hull if abs(hull.volume - abs(merged.volume)) <= 1e-6 * hull.volume else None


def occluders(meshes):
    """Per target: (triangles it occludes with, whether it can shadow itself)."""
    out = []
    for mesh in meshes:
        hull = None if _planar(mesh) else _convex_hull(mesh)
        tris = hull.triangles if hull is not None else mesh.triangles
        out.append((np.asarray(tris, np.float64), hull is None and not _planar(mesh)))
    return out


def visibility(facets, laser, spots, meshes, which: int, caster=any_hit):
    """(D, F) bool: facet f of target `which` sees the laser spot and detector spot d, or None
    when nothing in the scene can block it (one target that cannot shadow itself)."""
    occ = occluders(meshes)
    tris = [t for i, (t, self_shadow) in enumerate(occ) if i != which or self_shadow]
    if not tris:
        return None
    tris = np.concatenate(tris)
    c, n = facets.centres, facets.normals
    origins = c + OFFSET_M * n
    spots = np.asarray(spots, np.float64)
    to_laser = np.asarray(laser, np.float64) - c
    front = np.einsum("fk,fk->f", n, to_laser) > 0
    sees_laser = np.zeros(len(c), bool)
    sees_laser[front] = ~caster(origins[front], to_laser[front], tris)
    out = np.zeros((len(spots), len(c)), bool)
    for d, spot in enumerate(spots):
        to_spot = spot - c
        todo = sees_laser & (np.einsum("fk,fk->f", n, to_spot) > 0)
        out[d, todo] = ~caster(origins[todo], to_spot[todo], tris)
    return out


def scene_visibility(facet_sets, laser, spots, meshes, caster=any_hit) -> list:
    """`visibility` for every target at once: [(D, F_i) bool or None]. The occluders (hulls)
    are found once and every target's rays are cast together, D + 1 caster calls in all, so a
    scene of many small targets costs its triangles and rays, not targets^2 hull and ray-caster
    builds (5,000 small spheres: hours before). A target's own triangles are among the
    occluders even where it cannot shadow itself: a ray leaving a plane or a convex solid on
    its front side never meets it again, so the masks are those of `visibility`."""
    occ = occluders(meshes)
    if len(meshes) == 1 and not occ[0][1]:
        return [None]
    tris = np.concatenate([t for t, _ in occ])
    c = np.concatenate([f.centres for f in facet_sets])
    n = np.concatenate([f.normals for f in facet_sets])
    origins = c + OFFSET_M * n
    to_laser = np.asarray(laser, np.float64) - c
    sees_laser = np.einsum("fk,fk->f", n, to_laser) > 0
    sees_laser[sees_laser] = ~caster(origins[sees_laser], to_laser[sees_laser], tris)
    out = np.zeros((len(spots), len(c)), bool)
    for d, spot in enumerate(np.asarray(spots, np.float64)):
        to_spot = spot - c
        todo = sees_laser & (np.einsum("fk,fk->f", n, to_spot) > 0)
        out[d, todo] = ~caster(origins[todo], to_spot[todo], tris)
    ends = np.cumsum([f.count for f in facet_sets])[:-1]
    return np.split(out, ends, axis=1)
