"""The Toon BSDF (Cycles' closure/bsdf_toon.h, from OSL): light within a cone is taken at full
strength, fading linearly to 0 over `smooth` beyond it. Its half-angles are size * pi/2 and
smooth * pi/2 (size clamped to [1e-5, 1], smooth to [0, 1]); directions are sampled uniformly
in the cone of half-angle theta_s = min(size + smooth, pi/2), pdf_c = 1 / (2 pi (1 - cos theta_s)).
The Diffuse component's cone is around the shading normal and measures the angle of wi; the
Glossy component's is around wo mirrored about the normal and measures wi's angle to it.
Cycles defines f cos = I(angle) pdf_c (f cos, not f, is what it makes constant), so
f = I pdf_c / cos(wi). That Glossy f cos is symmetric in wo and wi; Diffuse's is not, and its
adjoint f(wi, wo) (light particles) is constant in wi, sampled cosine-weighted.

Material table: size in lobe_roughness, smooth in lobe_exponent, the component in
lobe_distribution (TOON_DIFFUSE or TOON_GLOSSY: where the cone is centred)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...scene import LOBE_TOON, RAY_DIFFUSE, RAY_GLOSSY, TOON_GLOSSY
from ... import sampling
from .. import diffuse
from . import inputs
from .base import (CLASS_DIFFUSE, CLASS_GLOSSY, LABEL_DIFFUSE, LABEL_GLOSSY, LobeSample, SurfaceLobe, SurfaceParams,
                   mean_albedo)

HALF_PI = 0.5 * np.pi


@dataclass
class ToonParams(SurfaceParams):
    """size, smooth (K,) half-angles in radians (Cycles' bsdf_toon_setup_common); glossy (K,)
    bool: the Glossy component."""

    size: np.ndarray
    smooth: np.ndarray
    glossy: np.ndarray


def intensity(size, smooth, angle):
    """Cycles' bsdf_toon_get_intensity: 1 inside the cone, a linear fall-off over smooth, 0 past."""
    fade = np.divide(angle - size, smooth, out=np.ones_like(angle), where=smooth > 0)
    return np.where(angle < size, 1.0, np.where((angle < size + smooth) & (smooth > 0), 1.0 - fade, 0.0))


def one_minus_cos_sample(p) -> np.ndarray:
    """(K,) 1 - cos of the sampled cone's half-angle min(size + smooth, pi/2)."""
    theta = np.minimum(p.size + p.smooth, HALF_PI)
    return 2.0 * np.sin(0.5 * theta) ** 2


def _mirror(w):
    r = -w
    r[:, 2] = w[:, 2]
    return r


class Toon(SurfaceLobe):
    kind = LOBE_TOON
    rays = RAY_DIFFUSE | RAY_GLOSSY  # both components' (per row: row_facts)
    reflection_class = transmission_class = CLASS_DIFFUSE

    def parameters(self, m, lobe, point, src, inside) -> ToonParams:
        size = np.clip(inputs.roughness(m, lobe, point, src), 1e-5, 1.0) * HALF_PI
        smooth = np.clip(inputs.exponent(m, lobe, src), 0.0, 1.0) * HALF_PI
        return ToonParams(color=inputs.color(m, lobe, point, src), delta=np.zeros(len(lobe), bool),
                          size=size, smooth=smooth, glossy=m.lobe_distribution[lobe] == TOON_GLOSSY)

    def albedo(self, p, wo):
        return p.color  # Cycles' estimate: the closure's weight

    def albedo_parts(self, p, wo, weight, estimate):
        glossy = p.glossy[:, None]
        return [(CLASS_DIFFUSE, np.where(glossy, 0.0, estimate)), (CLASS_GLOSSY, np.where(glossy, estimate, 0.0))]

    def row_facts(self, p):
        """Cycles' Diffuse Toon is a diffuse closure, its Glossy Toon a glossy one (passes, light
        visibility)."""
        return (np.where(p.glossy, CLASS_GLOSSY, CLASS_DIFFUSE),
                np.where(p.glossy, RAY_GLOSSY, RAY_DIFFUSE).astype(np.uint8))

    def _axis(self, p, wo):
        """(K,3) the cone's axis: the normal (Diffuse) or wo's mirror direction (Glossy)."""
        axis = np.zeros_like(wo)
        axis[:, 2] = 1.0
        return np.where(p.glossy[:, None], _mirror(wo), axis)

    def _forward(self, p, wo, wi):
        """f (K,3) and the cone pdf (K,) of the lobe as Cycles evaluates it (wo the view side)."""
        cos_i = wi[:, 2]
        angle = np.arccos(np.clip(np.sum(self._axis(p, wo) * wi, axis=1), -1.0, 1.0))
        theta_s = np.minimum(p.size + p.smooth, HALF_PI)
        ok = (cos_i > 0) & (angle < theta_s) & ((wo[:, 2] > 0) | ~p.glossy)
        pdf_c = sampling.pdf_sphere_cone(one_minus_cos_sample(p))
        fcos = np.where(ok, intensity(p.size, p.smooth, angle) * pdf_c, 0.0)
        f = np.divide(fcos, cos_i, out=np.zeros_like(fcos), where=ok)
        return p.color * f[:, None], np.where(ok, pdf_c, 0.0)

    def eval(self, p, wo, wi):
        if not p.adjoint:
            return self._forward(p, wo, wi)
        f, _ = self._forward(p, wi, wo)  # f(wi, wo)
        return f, self.pdf(p, wo, wi)

    def pdf(self, p, wo, wi):
        if not p.adjoint:
            return self._forward(p, wo, wi)[1]
        cone = self._forward(p, wo, wi)[1]
        return np.where(p.glossy, cone, diffuse.pdf(wi[:, 2]))

    def sample(self, p, wo, u, u_branch) -> LobeSample:
        theta_s = np.minimum(p.size + p.smooth, HALF_PI)
        local, one_minus_cos = sampling.sample_sphere_cone(u, np.sin(theta_s) ** 2)
        axis = self._axis(p, wo)
        wi = sampling.to_world(local, *sampling.frame_from_z(axis), axis)
        above = (wi[:, 2] > 0) & ((wo[:, 2] > 0) | ~p.glossy)
        pdf = np.where(above, sampling.pdf_sphere_cone(one_minus_cos), 0.0)
        if p.adjoint:  # the Diffuse adjoint is constant in wi: cosine-weighted
            wi = np.where(p.glossy[:, None], wi, diffuse.sample(u))
            pdf = np.where(p.glossy, pdf, diffuse.pdf(wi[:, 2]))
        label = np.where(p.glossy, LABEL_GLOSSY, LABEL_DIFFUSE).astype(np.int8)
        return LobeSample(wi=wi, pdf=pdf, delta=False, label=label)

    def stores_photons(self, m, lobe, min_roughness):
        return np.ones(len(lobe), bool)  # a cone of positive width: density estimation converges

    def analysis_albedo(self, m, lobe, color, min_roughness):
        a = np.maximum(mean_albedo(m, lobe, color), 0.0)
        glossy = m.lobe_distribution[lobe] == TOON_GLOSSY
        return {"diffuse": np.where(glossy, 0.0, a), "glossy": np.where(glossy, a, 0.0)}
