"""The visible setup (wall, laser spot O, detector spots, pulse) and the hidden target mesh.

Coordinates (DESIGN.md): the relay wall is the plane y = 0 with normal +y pointing into the
hidden area (y > 0); z is up. SI units everywhere: metres, seconds, watts, joules.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import trimesh

from ..core.constants import FWHM_PER_SIGMA, PAPER_PULSE_FWHM_S
from ..core.errors import require
from ..core.limits import MAX_SCENE_TARGETS, require_count
from ..core.geometry import (Facets, as_point, coincident_pair,  # noqa: F401  (Facets: re-exported)
                             morton_order)
from ..core.tuning import FACET_M
from .meshes import rectangle
from .reflectance import Lambertian, as_reflectance


@dataclass(frozen=True)
class Pulse:
    """A Gaussian laser pulse P0(t) = energy * N(t; peak_delay, sigma) (paper Eq. 9, 22, 23)."""

    energy_j: float = 0.75 / 80e6  # 750 mW at 80 MHz = 9.375e-9 J per pulse
    fwhm_s: float = PAPER_PULSE_FWHM_S

    def __post_init__(self):
        require(math.isfinite(self.energy_j) and self.energy_j > 0, "pulse.energy_j",
                f"must be a positive number of joules, got {self.energy_j}",
                "pass the pulse energy, e.g. Pulse.from_laser(power_w=0.75, rep_rate_hz=80e6)")
        require(math.isfinite(self.fwhm_s) and self.fwhm_s > 0, "pulse.fwhm_s",
                f"must be a positive duration in seconds, got {self.fwhm_s}",
                "pass the pulse FWHM in seconds, e.g. 70e-12")

    @classmethod
    def from_laser(cls, power_w: float = 0.75, rep_rate_hz: float = 80e6,
                   fwhm_s: float = PAPER_PULSE_FWHM_S) -> "Pulse":
        return cls(energy_j=power_w / rep_rate_hz, fwhm_s=fwhm_s)

    @property
    def sigma_s(self) -> float:
        return self.fwhm_s / FWHM_PER_SIGMA

    @property
    def peak_delay_s(self) -> float:
        """The paper puts the pulse peak at mu = 3 sigma after emission (Section 3.1)."""
        return 3.0 * self.sigma_s


def _disc_area(diameter_m: float) -> float:
    return math.pi * (0.5 * diameter_m) ** 2


@dataclass(frozen=True)
class Setup:
    """Everything visible: laser spot O and detector spots on the wall, device distance, BRDF.

    The device (laser and detectors) sits ``device_distance_m`` from the wall; the two legs to
    and from the wall add 2 d / c to every arrival time. ``aperture_area_m2`` is the detector's
    collecting area S_d of paper Eq. 21, which the paper does not state: the default is a
    1-inch lens. Amplitudes scale with it; positions do not.
    """

    laser_spot: np.ndarray = field(default_factory=lambda: np.zeros(3))
    detector_spots: np.ndarray = field(
        default_factory=lambda: np.array([[-0.5, 0.0, 0.0], [-1.0, 0.0, 0.0], [-1.5, 0.0, 0.0]]))
    device_distance_m: float = 20.0
    laser_spot_diameter_m: float = 0.07
    detected_spot_diameter_m: float = 0.1
    aperture_area_m2: float = _disc_area(0.0254)
    wall_brdf: float = 0.2579
    pulse: Pulse = field(default_factory=Pulse)
    finite_spots: bool = False  # True: the spots are disks of the diameters above

    def __post_init__(self):
        laser = as_point(self.laser_spot, "setup.laser_spot")
        spots = np.array(self.detector_spots, dtype=np.float64)
        if spots.ndim == 1 and spots.shape == (3,):
            spots = spots[None, :]
        require(spots.ndim == 2 and spots.shape[1] == 3 and spots.shape[0] >= 1,
                "setup.detector_spots", f"expected shape (n_detectors, 3), got {spots.shape}",
                "pass one [x, y, z] row per detector spot")
        require(bool(np.all(np.isfinite(spots))), "setup.detector_spots",
                "contains NaN or inf", "pass finite coordinates in metres")
        for name, pts in (("setup.laser_spot", laser[None, :]), ("setup.detector_spots", spots)):
            require(bool(np.all(np.abs(pts[:, 1]) < 1e-9)), name,
                    f"points must lie on the wall plane y = 0, got y = {pts[:, 1].tolist()}",
                    "set the y coordinate of every wall spot to 0")
        require(coincident_pair(spots, 1e-6) is None, "setup.detector_spots",
                "two detector spots coincide, so their ellipses carry the same information",
                "give every detector its own spot on the wall")
        require(bool(np.all(np.linalg.norm(spots - laser, axis=1) > 1e-6)), "setup.detector_spots",
                "a detector spot coincides with the laser spot O (the direct wall return "
                "would swamp it)", "move the detector spot away from the laser spot")
        for name in ("device_distance_m", "laser_spot_diameter_m", "detected_spot_diameter_m",
                     "aperture_area_m2", "wall_brdf"):
            value = getattr(self, name)
            require(isinstance(value, (int, float)) and math.isfinite(value) and value > 0,
                    f"setup.{name}", f"must be a positive finite number, got {value!r}",
                    "pass a positive value in SI units")
        require(isinstance(self.finite_spots, (bool, np.bool_)), "setup.finite_spots",
                f"must be true or false, got {self.finite_spots!r}",
                "pass True for disk spots, False for the paper's point spots")
        laser.flags.writeable = False
        spots.flags.writeable = False
        object.__setattr__(self, "laser_spot", laser)
        object.__setattr__(self, "detector_spots", spots)

    @property
    def n_detectors(self) -> int:
        return self.detector_spots.shape[0]

    def spot_samples(self):
        """The spots as quadrature points: (laser points (L, 3), laser weights (L,), detector
        offsets (J, 3), detector weights (J,)). Point spots: one point of weight 1 each.
        Finite spots: each disk (in the wall plane, x and z) by the 7-point rule exact for
        polynomials of degree 5 over a disk (Stroud S2:5-2: the centre 1/4, six points at
        sqrt(2/3) of the radius 1/8 each); the signal is the weighted mean over both disks."""
        if not self.finite_spots:
            return self.laser_spot[None], np.ones(1), np.zeros((1, 3)), np.ones(1)
        angles = np.arange(6) * (np.pi / 3)
        ring = np.stack([np.cos(angles), np.zeros(6), np.sin(angles)], axis=1) * math.sqrt(2 / 3)
        unit = np.concatenate([np.zeros((1, 3)), ring])
        weights = np.array([0.25] + [0.125] * 6)
        laser = self.laser_spot + 0.5 * self.laser_spot_diameter_m * unit
        return laser, weights, 0.5 * self.detected_spot_diameter_m * unit, weights

    @property
    def detected_spot_area_m2(self) -> float:
        return _disc_area(self.detected_spot_diameter_m)

    def power_scale(self, target_brdf: float) -> float:
        """W per (J * geometric weight): f_c f_w^2 S_A S_d / d^2 (paper Eq. 19-21).

        The laser spot area S_0 of Eq. 10 and 12 cancels.
        """
        return (target_brdf * self.wall_brdf ** 2 * self.detected_spot_area_m2
                * self.aperture_area_m2 / self.device_distance_m ** 2)


@dataclass(frozen=True)
class Target:
    """A hidden object: any triangle mesh and how it reflects. `brdf` is a number (a Lambertian
    BRDF f_c in 1/sr; the paper's clothes 0.1284) or a reflectance model (physics.reflectance)."""

    mesh: trimesh.Trimesh
    brdf: object = 0.1284

    def __post_init__(self):
        mesh = self.mesh
        require(isinstance(mesh, trimesh.Trimesh), "target.mesh",
                f"expected a trimesh.Trimesh, got {type(mesh).__name__}",
                "load it with nlos_cl.load_mesh(path) or build one with nlos_cl.rectangle/box/sphere")
        require(len(mesh.faces) > 0, "target.mesh", "the mesh has no faces",
                "pass a mesh with at least one triangle")
        require(bool(np.all(np.isfinite(mesh.vertices))), "target.mesh",
                "vertices contain NaN or inf", "clean the mesh before passing it")
        require(float(mesh.area) > 0, "target.mesh",
                "every face is degenerate (total area 0)", "pass a mesh with non-zero area")
        reflectance = as_reflectance(self.brdf)  # validates
        if isinstance(reflectance, Lambertian):  # keep `brdf` the number the user gave
            object.__setattr__(self, "brdf", reflectance.brdf)
        ymin = float(mesh.vertices[:, 1].min())
        require(ymin > 0, "target.mesh",
                f"reaches y = {ymin:.4g} m, on or behind the relay wall (the hidden area is y > 0)",
                "move the target into y > 0, e.g. mesh.apply_translation([0, d, 0])")
        # Keep our own copy: later edits to the caller's mesh must not change this target.
        object.__setattr__(self, "mesh", mesh.copy())

    @property
    def reflectance(self):
        return as_reflectance(self.brdf)

    def facets(self, facet_size_m: float = FACET_M) -> Facets:
        """Subdivide until every triangle edge is at most facet_size_m; drop zero-area faces.

        Faces on the mesh's boundary or on a crease (the silhouette where the shortest path
        lies) are cut 16-fold more (`_refine_edges`): their centres then sit within 1/12 of a
        facet of the edge, so the signal's onset matches the continuous surface's.

        Facets are put in Morton (Z-curve) order of their centres so that neighbours in memory
        are neighbours in space: the forward kernel culls whole chunks of facets at once.
        """
        require(math.isfinite(facet_size_m) and facet_size_m > 0, "facet_size_m",
                f"must be a positive length in metres, got {facet_size_m}", "pass e.g. 0.01")
        mesh = self.mesh
        # subdivide_to_size halves a face's edges until its longest is <= f: 4^k triangles
        # each; refused before trimesh allocates them (meshes.FACET_BYTES each, in the end)
        lengths = mesh.edges_unique_length
        k = np.ceil(np.log2(np.maximum(lengths[mesh.faces_unique_edges].max(axis=1)
                                       / facet_size_m, 1.0)) - 1e-9)
        from .meshes import require_facets
        require_facets(float(np.exp2(2.0 * np.maximum(k, 0.0)).sum()),
                       f"this {float(mesh.area):.3g} m^2 target", facet_size_m)
        longest = float(lengths.max())
        vertices, faces = mesh.vertices, mesh.faces
        if longest > facet_size_m:
            iterations = int(math.ceil(math.log2(longest / facet_size_m))) + 2
            vertices, faces = trimesh.remesh.subdivide_to_size(
                vertices, faces, max_edge=facet_size_m, max_iter=iterations)
        tri = _refine_edges(vertices, faces)
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        doubled = np.linalg.norm(cross, axis=1)
        keep = doubled > 1e-12 * max(longest, 1e-9) ** 2
        require(bool(keep.any()), "target.mesh", "all faces are degenerate after subdivision",
                "pass a mesh with non-zero area")
        centres = tri[keep].mean(axis=1)
        normals = cross[keep] / doubled[keep, None]
        areas = 0.5 * doubled[keep]
        order = morton_order(centres)
        return Facets(centres[order], normals[order], areas[order])


EDGE_LEVELS = 2  # boundary and crease faces are cut into 4^2 pieces
CREASE_RAD = math.radians(30.0)


def _split4(tri: np.ndarray) -> np.ndarray:
    """(M, 3, 3) triangles -> (4 M, 3, 3): the midpoint subdivision."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
    return np.concatenate([np.stack(t, axis=1) for t in
                           ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])


def _refine_edges(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F', 3, 3) triangles: faces with an edge on the mesh's boundary or on a crease (dihedral
    angle over 30 degrees) cut EDGE_LEVELS times in four, the others as they are. A facet's
    centre sits a third of its height inside an edge; the onset comes from the edge."""
    merged = trimesh.Trimesh(vertices, faces, process=False)
    merged.merge_vertices()
    edges = np.sort(merged.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    codes = edges[:, 0].astype(np.int64) * (len(merged.vertices) + 1) + edges[:, 1]
    _, inverse, counts = np.unique(codes, return_inverse=True, return_counts=True)
    marked = (counts[inverse.ravel()] == 1).reshape(-1, 3).any(axis=1)
    if len(merged.face_adjacency):
        marked[merged.face_adjacency[merged.face_adjacency_angles > CREASE_RAD].ravel()] = True
    tri = vertices[faces]
    fine = tri[marked]
    for _ in range(EDGE_LEVELS):
        fine = _split4(fine)
    return np.concatenate([tri[~marked], fine])


@dataclass(frozen=True)
class Scene:
    """A setup, the hidden target(s), and how finely they are cut into facets.

    `target` is the first target; `more_targets` are further ones (a second object, static
    clutter). Light is third-order only (one bounce on a target), so each target's signal is
    simulated on its own and the signals add; with `occlusion` (the default) a facet counts
    only where no triangle of any target blocks its way to the laser or detector spot. `truth` is the first target's centre (its
    bounding-box centre unless given); `truths` has every target's, in order.
    """

    setup: Setup
    target: Target
    facet_size_m: float = FACET_M
    truth: np.ndarray | None = None  # where the target "is" (its centre), for error reports
    more_targets: tuple = ()
    occlusion: bool = True  # facets contribute only where they see both spots (visibility.py)

    def __post_init__(self):
        require(isinstance(self.setup, Setup), "scene.setup", "expected a nlos_cl.Setup",
                "build one with nlos_cl.Setup(...)")
        require(isinstance(self.target, Target), "scene.target", "expected a nlos_cl.Target",
                "wrap your mesh: nlos_cl.Target(mesh)")
        more = tuple(self.more_targets)
        require_count("scene.more_targets", 1 + len(more), MAX_SCENE_TARGETS, "targets", "join "
                      "small objects into one mesh target (trimesh.util.concatenate)")
        for i, t in enumerate(more):
            require(isinstance(t, Target), f"scene.more_targets[{i}]", "expected a "
                    f"nlos_cl.Target, got {type(t).__name__}", "wrap each mesh in nlos_cl.Target")
        object.__setattr__(self, "more_targets", more)
        truth = self.truth
        if truth is None:
            truth = self.target.mesh.bounds.mean(axis=0)
        truth = as_point(truth, "scene.truth")
        truth.flags.writeable = False
        object.__setattr__(self, "truth", truth)

    @property
    def targets(self) -> tuple:
        return (self.target,) + self.more_targets

    @property
    def truths(self) -> np.ndarray:
        """(K, 3) centres: `truth` for the first target, bounding-box centres for the others."""
        rest = [t.mesh.bounds.mean(axis=0) for t in self.more_targets]
        return np.array([self.truth, *rest]).reshape(-1, 3)

    def facets(self, which: int = 0) -> Facets:
        """Target `which` cut into facets, computed once per scene (a scene is immutable)."""
        cache = self.__dict__.setdefault("_facets", {})
        if which not in cache:
            cache[which] = self.targets[which].facets(self.facet_size_m)
        return cache[which]

    def use_facets(self, which: int, facets: Facets) -> None:
        """Take `facets` as target `which`'s cut (a frame of a sequence: the mesh cut once,
        moved), instead of cutting it again; they must be that target's facets."""
        self.__dict__.setdefault("_facets", {})[which] = facets

    def visibility(self, which: int = 0):
        """(D, F) bool: facet f of target `which` sees the laser spot and detector spot d
        through the whole scene (every target's triangles), computed once per scene; None when
        occlusion is off or nothing can block (one planar or convex target). Finite spots are
        tested from their centres."""
        if not self.occlusion:
            return None
        if "_visibility" not in self.__dict__:  # every target's at once (visibility.py)
            from .visibility import scene_visibility
            self.__dict__["_visibility"] = scene_visibility(
                [self.facets(i) for i in range(len(self.targets))], self.setup.laser_spot,
                self.setup.detector_spots, [t.mesh for t in self.targets])
        return self.__dict__["_visibility"][which]


def paper_setup(**overrides) -> Setup:
    """The paper's Section 3.1 configuration: O at the origin, A, B, C at x = -0.5, -1, -1.5."""
    return Setup(**overrides)


def paper_scene(position=(4.0, 2.0, 0.0), facet_size_m: float = FACET_M, **setup_overrides) -> Scene:
    """The paper's whole simulation setup in one call: its 0.3 m x 1.6 m upright rectangle at
    `position` (default (4, 2, 0)), facing the wall side, cut into `facet_size_m` facets."""
    mesh = rectangle(centre=position, cell_m=facet_size_m)
    return Scene(paper_setup(**setup_overrides), Target(mesh), facet_size_m, truth=position)
