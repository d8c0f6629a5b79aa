"""How the hidden target reflects: the seam the forward model is specialised on.

A reflectance model splits the target's BRDF f(n, to_laser, to_detector) into a constant
`scale` (1/sr, applied on the host in float64 with the other physical constants) and a
dimensionless, direction-dependent `factor` that the forward kernel evaluates per (facet,
detector). The kernel gets the factor as the macro REFLECTANCE_FACTOR(n, to_laser, to_detector)
through `kernel_defines()`; `factor()` is its float64 twin. Lambertian reflection (the paper's)
has factor 1; GGX (glossy) and Retroreflective (retroreflective sheeting) add their own macro
and twin here and, for the macro's function, in forward.cl.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..core.errors import require


@dataclass(frozen=True)
class Lambertian:
    """A diffuse reflector: f = brdf (1/sr) in every direction (paper: clothes 0.1284)."""

    brdf: float = 0.1284

    def __post_init__(self):
        require(isinstance(self.brdf, (int, float)) and math.isfinite(self.brdf)
                and self.brdf > 0, "target.brdf", f"must be a positive number, got {self.brdf!r}",
                "pass e.g. 0.1284 (the paper's clothes; 1/pi is a perfect white reflector)")

    @property
    def scale(self) -> float:
        return float(self.brdf)

    def kernel_defines(self) -> dict:
        return {}  # forward.cl's default REFLECTANCE_FACTOR is 1

    def factor(self, normals, to_laser, to_detector) -> np.ndarray:
        """(D, F) direction-dependent part: 1 for a Lambertian surface."""
        return np.ones(to_detector.shape[:-1])


def _number(field: str, value, low: float, high: float, fix: str) -> float:
    require(isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value) and low <= value <= high, field,
            f"must be a number in [{low}, {high}], got {value!r}", fix)
    return float(value)


def _albedo(what: str, total: float, fix: str) -> None:
    """A model's parts' albedos summed: some light reflected, never more than received."""
    require(total > 0, "reflectance", f"{what} is 0: the target reflects nothing", fix)
    require(total <= 1.0, "reflectance", f"{what} exceeds 1: the surface would reflect more "
            "light than it receives", fix)


class _LobeOverDiffuse:
    """A lobe over a diffuse base (GGX, Retroreflective), named as the class is declared:
    `lobe` the field of the lobe's albedo, `knob` = (field, upper bound) its shape (>= 1e-3),
    `example` what the fix suggests; both albedos in [0, 1], their sum an albedo.
    scale = (lobe + diffuse) / pi."""
    LOBE: ClassVar[str]
    KNOB: ClassVar[tuple[str, float]]
    EXAMPLE: ClassVar[str]
    diffuse: float

    def __init_subclass__(cls, *, lobe: str, knob: tuple[str, float], example: str, **kw):
        super().__init_subclass__(**kw)
        cls.LOBE, cls.KNOB, cls.EXAMPLE = lobe, knob, example

    def __post_init__(self):
        fix, lobe, (knob, high) = f"pass e.g. {self.EXAMPLE}", getattr(self, self.LOBE), self.KNOB
        _number(f"reflectance.{self.LOBE}", lobe, 0.0, 1.0, fix)
        _number("reflectance.diffuse", self.diffuse, 0.0, 1.0, fix)
        _number(f"reflectance.{knob}", getattr(self, knob), 1e-3, high, fix)
        _albedo(f"{self.LOBE} + diffuse", lobe + self.diffuse, fix)

    @property
    def scale(self) -> float:
        return (getattr(self, self.LOBE) + self.diffuse) / math.pi


@dataclass(frozen=True)
class GGX(_LobeOverDiffuse, lobe="specular", knob=("roughness", 1.0),
          example="GGX(specular=0.5, roughness=0.3, diffuse=0.1)"):
    """A glossy surface: a GGX (Trowbridge-Reitz) microfacet lobe over an optional diffuse
    base, f = diffuse / pi + specular D(h) G(l, v) / (4 cos_l cos_v), with
    D(h) = a^2 / (pi ((n.h)^2 (a^2 - 1) + 1)^2) and Smith's separable masking-shadowing
    G = G1(l) G1(v), G1 = 2 / (1 + sqrt(1 + a^2 tan^2)); `roughness` is a (Walter et al. 2007).
    It conserves energy for diffuse + specular <= 1 (the microfacet lobe reflects at most
    `specular` of the light; single scattering loses some at high roughness). Mitsuba's
    roughconductor (distribution ggx, material none, specular_reflectance = `specular`)
    blended with a diffuse BSDF is the same function. scale = (diffuse + specular) / pi."""

    specular: float = 0.5
    roughness: float = 0.3
    diffuse: float = 0.0

    def _weights(self):
        total = self.specular + self.diffuse
        return self.roughness ** 2, self.diffuse / total, self.specular / total

    def kernel_defines(self) -> dict:
        a2, kd, ks = self._weights()
        return {"GGX_A2": f"{a2:.9e}f", "GGX_KD": f"{kd:.9e}f", "GGX_KS": f"{ks:.9e}f",
                "REFLECTANCE_FACTOR(n,l,v)": "ggx_factor(n,l,v)"}

    def factor(self, normals, to_laser, to_detector) -> np.ndarray:
        """(D, F) f / scale: KD + KS a^2 / den^2 G1(l) G1(v) / (4 cos_l cos_v) (the pi of D
        cancels against the scale's); 0 where either direction is below the surface."""
        h = to_laser[None] + to_detector
        ch = np.einsum("fk,dfk->df", normals, h) / np.linalg.norm(h, axis=-1)
        return self._of(np.einsum("fk,fk->f", normals, to_laser)[None],
                        np.einsum("fk,dfk->df", normals, to_detector), ch)

    def factor_of_cosines(self, cos_l, cos_v, cos_lv) -> np.ndarray:
        """f / scale from n.l, n.v and l.v (n.h = (n.l + n.v) / |l + v|, |l + v|^2 =
        2 + 2 l.v): the host models' form, which has these without (D, F, 3) temporaries."""
        cos_l, cos_v = np.asarray(cos_l, np.float64), np.asarray(cos_v, np.float64)
        half = np.sqrt(np.maximum(2.0 + 2.0 * np.asarray(cos_lv, np.float64), 1e-300))
        return self._of(cos_l, cos_v, (cos_l + cos_v) / half)

    def _of(self, cl, cv, ch) -> np.ndarray:
        a2, kd, ks = self._weights()
        den = ch * ch * (a2 - 1.0) + 1.0
        ok = (cl > 0) & (cv > 0)
        cl, cv = np.where(ok, cl, 1.0), np.where(ok, cv, 1.0)
        g1 = lambda c: 2.0 / (1.0 + np.sqrt(1.0 + a2 * (1.0 - c * c) / (c * c)))  # noqa: E731
        spec = a2 / (den * den) * g1(cl) * g1(cv) / (4.0 * cl * cv)
        return np.where(ok, kd + ks * spec, 0.0)


@dataclass(frozen=True)
class Retroreflective(_LobeOverDiffuse, lobe="retro", knob=("width_rad", 1e3),
                      example="Retroreflective(retro=0.7, width_rad=0.005, diffuse=0.2)"):
    """Retroreflective sheeting or tape (glass beads, prisms): a diffuse base plus a lobe
    around the retro direction, f = diffuse / pi + retro exp(-|l - v|^2 / (2 w^2)) / A(w),
    A(w) = 2 pi (lam - 1 + e^-lam) / lam^2, lam = 1 / w^2. l, v: unit directions from the
    surface to the light and to the detector; |l - v|^2 = 2 (1 - l.v), so near the retro
    direction the lobe is a Gaussian of the angle psi between them, sd w = `width_rad`.
    It is Lafortune's retro-reflective lobe (l.v)^n (Lafortune et al. 1997, C = (1, 1, 1)) in
    its spherical-Gaussian form exp(n (l.v - 1)), n = 1 / w^2, which unlike (l.v)^n becomes
    constant as w grows: the model then is Lambertian, brdf (diffuse + retro) / pi.
    A(w) is the lobe's albedo at normal incidence, so `retro` is the fraction of normally
    incident light the lobe sends back; at any other incidence it sends less (a lobe centred
    on l sees smaller cosines; spherical rearrangement, checked by quadrature in the tests),
    so the albedo never exceeds diffuse + retro <= 1. Reciprocal: |l - v| = |v - l|.
    Default width 0.005 rad (0.3 deg): Greg Ward's glass-bead fit (Radiance lib/retrorefl.cal)
    falls to 1/4 of its peak at a 0.5 deg observation angle. scale = (diffuse + retro) / pi."""

    retro: float = 0.7
    width_rad: float = 0.005
    diffuse: float = 0.2

    def _weights(self):
        """(lam / 2, diffuse part, lobe peak), the last two over `scale`."""
        lam = 1.0 / self.width_rad ** 2
        # lam - 1 + e^-lam without cancellation as lam -> 0 (wide lobes): its series there
        if lam > 1e-3:
            tail = lam + math.expm1(-lam)
        else:
            tail = lam * lam * (0.5 - lam / 6 + lam * lam / 24)
        albedo_normal = 2.0 * math.pi * tail / (lam * lam)  # A(w); pi as w -> infinity
        total = self.retro + self.diffuse
        return 0.5 * lam, self.diffuse / total, self.retro * math.pi / (albedo_normal * total)

    def kernel_defines(self) -> dict:
        half_lam, kd, kl = self._weights()
        return {"RETRO_HALF_LAM": f"{half_lam:.9e}f", "RETRO_KD": f"{kd:.9e}f",
                "RETRO_KL": f"{kl:.9e}f", "REFLECTANCE_FACTOR(n,l,v)": "retro_factor(l,v)"}

    def factor_of_cosine(self, cos_lv) -> np.ndarray:
        """f / scale from l.v alone, where both directions are above the surface (the model
        depends on nothing else): for float64 hosts that have l.v without (D, F, 3)
        temporaries (localization/model/forward/batch.py). 1 - l.v keeps ~1e-16 / (1 - l.v) relative
        precision in float64, ample for lobes of width >= 1e-3 rad."""
        half_lam, kd, kl = self._weights()
        return kd + kl * np.exp(-2.0 * half_lam * (1.0 - np.asarray(cos_lv, np.float64)))

    def factor_of_cosines(self, cos_l, cos_v, cos_lv) -> np.ndarray:
        """The host models' form (GGX.factor_of_cosines): l.v alone shapes this lobe."""
        return self.factor_of_cosine(cos_lv)

    def factor(self, normals, to_laser, to_detector) -> np.ndarray:
        """(D, F) f / scale: KD + KL exp(-(lam / 2) |l - v|^2) (|l - v|^2 from the difference,
        not 2 (1 - l.v), which cancels near the retro direction); 0 below the surface."""
        half_lam, kd, kl = self._weights()
        cl = np.einsum("fk,fk->f", normals, to_laser)[None]
        cv = np.einsum("fk,dfk->df", normals, to_detector)
        gap = to_laser[None] - to_detector
        lobe = np.exp(-half_lam * np.einsum("dfk,dfk->df", gap, gap))
        return np.where((cl > 0) & (cv > 0), kd + kl * lobe, 0.0)


def from_spec(spec) -> object:
    """A reflectance from a scene file's `reflectance:` mapping, e.g. {model: ggx,
    specular: 0.5, roughness: 0.2, diffuse: 0.1}, {model: retroreflective, retro: 0.7,
    width_rad: 0.005, diffuse: 0.2} or {model: lambertian, brdf: 0.1284}."""
    require(isinstance(spec, dict) and spec.get("model") in MODELS, "reflectance.model",
            f"expected a mapping with model one of {sorted(MODELS)}, got {spec!r}",
            "write e.g. {model: ggx, specular: 0.5, roughness: 0.2}")
    args = {k: v for k, v in spec.items() if k != "model"}
    cls = MODELS[spec["model"]]
    unknown = set(args) - set(cls.__dataclass_fields__)
    require(not unknown, "reflectance", f"unknown key(s) {sorted(unknown)} for model "
            f"{spec['model']}", f"use {sorted(cls.__dataclass_fields__)}")
    return cls(**args)


def as_reflectance(value):
    """A number means a Lambertian BRDF of that value; a model passes through."""
    if isinstance(value, (int, float, np.floating)) and not isinstance(value, bool):
        return Lambertian(float(value))
    require(hasattr(value, "kernel_defines") and hasattr(value, "factor")
            and hasattr(value, "scale"), "target.brdf",
            f"expected a number or a reflectance model, got {type(value).__name__}",
            "pass e.g. 0.1284 or nlos_cl.Lambertian(0.1284)")
    return value


MODELS = {"lambertian": Lambertian, "ggx": GGX, "retroreflective": Retroreflective}
