"""The GGX reflection lobe (Glossy BSDF, Metallic, Principled metallic and specular layers):
F D G2 / (4 cos_o cos_i), a perfect mirror when smooth (formulas: engine/bsdf/microfacet.py).

Its Fresnel colour F per FRESNEL_* model (Cycles' svm/closure.h): none (F = colour, Glossy
BSDF), F82-tint conductor (f0 = colour, edge tint = tint; Principled metallic) and the exact
dielectric Fresnel of ior remapped to F0(ior) tint .. 1 (Principled specular). Where the node
asked for Multiscatter GGX, the lobe is scaled by Cycles' energy factor (engine/bsdf/multiscatter.py),
and what is estimated from it (its selection weight, the layer weight it leaves the diffuse
base) sees its albedo times c E, as Cycles' closure weight carries that factor."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...scene import FRESNEL_DIELECTRIC, FRESNEL_F82, LOBE_MICROFACET, RAY_GLOSSY
from ...vec import dot, normalize
from .. import fresnel, layering, microfacet, multiscatter
from . import inputs
from .base import CLASS_GLOSSY, LABEL_GLOSSY, LobeSample, SurfaceLobe, SurfaceParams, mean_albedo

_MIRROR_XY = np.array([-1.0, -1.0, 1.0])  # reflection about the normal


@dataclass
class MicrofacetParams(SurfaceParams):
    """tint (K,3); roughness (K,) Blender's; alpha (K,) GGX (roughness^2, or Filter Glossy's);
    ior (K,); fresnel (K,) FRESNEL_*; multiscatter (K,) bool."""

    tint: np.ndarray
    roughness: np.ndarray
    alpha: np.ndarray
    ior: np.ndarray
    fresnel: np.ndarray
    multiscatter: np.ndarray


def fresnel_color(p: MicrofacetParams, cos: np.ndarray) -> np.ndarray:
    """Fresnel colour F (K,3) at cosines cos (K,) between wo and the microfacet normal."""
    F = p.color.copy()  # FRESNEL_NONE: the Glossy colour
    r = np.flatnonzero(p.fresnel == FRESNEL_F82)
    if len(r):
        F[r] = fresnel.f82_tint(p.color[r], np.minimum(p.tint[r], 1.0), cos[r])
    r = np.flatnonzero(p.fresnel == FRESNEL_DIELECTRIC)
    if len(r):
        eta = p.ior[r]
        F[r] = fresnel.dielectric_remapped(fresnel.f0_from_ior(eta)[:, None] * p.tint[r], cos[r], eta)
    return F


def fresnel_average(p: MicrofacetParams) -> np.ndarray:
    """Fss (K,3): the hemispherical average of each row's Fresnel colour, as Cycles estimates
    it per model (the Glossy colour itself, F82-tint's closed form, the remapped dielectric's
    fit)."""
    fss = p.color.copy()
    r = np.flatnonzero(p.fresnel == FRESNEL_F82)
    if len(r):
        fss[r] = multiscatter.f82_average(p.color[r], np.minimum(p.tint[r], 1.0))
    r = np.flatnonzero(p.fresnel == FRESNEL_DIELECTRIC)
    if len(r):
        fss[r] = multiscatter.remapped_dielectric_average(fresnel.f0_from_ior(p.ior[r])[:, None] * p.tint[r], p.ior[r])
    return fss


def energy_factor(p: MicrofacetParams, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(c (K,3), c E (K,3)): the Multiscatter GGX factor on the lobe and on what is estimated
    from its albedo; ones where the lobe is single-scattering."""
    c = np.ones((len(p), 3))
    cE = np.ones((len(p), 3))
    rows = np.flatnonzero(p.multiscatter)
    if len(rows):
        q = p.take(rows)
        c[rows], E = multiscatter.compensation(fresnel_average(q), q.roughness, np.clip(wo[rows, 2], 0.0, 1.0))
        cE[rows] = c[rows] * E[:, None]
    return c, cE


def specular_layer_weight(p, wo: np.ndarray) -> np.ndarray:
    """(K,) weight a dielectric specular layer (F0 = F0(ior) tint, roughness, ior) leaves to
    the lobes under it: Cycles' albedo estimate from its table (engine/bsdf/layering.py)."""
    f0 = fresnel.f0_from_ior(p.ior)[:, None] * p.tint
    # A glass lobe (engine/bsdf/lobes/dielectric.py) has no Multiscatter factor.
    scale = energy_factor(p, wo)[1] if getattr(p, "multiscatter", None) is not None else None
    return layering.base_weight(f0, p.roughness, wo[:, 2], p.ior, scale)


def blur(p, min_alpha: np.ndarray, is_delta) -> None:
    """Cycles' bsdf_microfacet_blur: alpha = max(alpha, min_alpha) (K,); is_delta(p) of the
    rows changed is refreshed. The albedo estimates keep the authored roughness, as Cycles
    keeps its energy terms."""
    rows = np.flatnonzero(min_alpha > p.alpha)
    if len(rows):
        p.alpha[rows] = min_alpha[rows]
        p.delta[rows] = is_delta(p.take(rows))


class Microfacet(SurfaceLobe):
    kind = LOBE_MICROFACET
    rays = RAY_GLOSSY
    reflection_class = transmission_class = CLASS_GLOSSY

    def parameters(self, m, lobe, point, src, inside) -> MicrofacetParams:
        color = inputs.color(m, lobe, point, src)
        roughness = inputs.roughness(m, lobe, point, src)
        alpha = microfacet.alpha_from_roughness(roughness)
        return MicrofacetParams(color=color, delta=microfacet.is_delta(alpha), tint=inputs.tint(m, lobe, color, src),
                                roughness=roughness, alpha=alpha, ior=inputs.ior(m, lobe, src), fresnel=m.lobe_fresnel[lobe],
                                multiscatter=m.lobe_multiscatter[lobe])

    def is_delta(self, p):
        return microfacet.is_delta(p.alpha)

    def albedo(self, p, wo):
        return fresnel_color(p, np.clip(wo[:, 2], 0.0, 1.0)) * energy_factor(p, wo)[1]

    def eval(self, p, wo, wi):
        h = normalize(wo + wi)
        F = fresnel_color(p, np.clip(dot(wo, h), 0.0, 1.0)) * energy_factor(p, wo)[0]
        return microfacet.eval_reflection(p.alpha, wo, wi, F), microfacet.pdf_reflection(p.alpha, wo, wi)

    def pdf(self, p, wo, wi):
        return microfacet.pdf_reflection(p.alpha, wo, wi)

    def sample(self, p, wo, u, u_branch) -> LobeSample:
        delta = p.delta
        if not delta.any():
            wi, _, pdf = microfacet.sample_reflection(p.alpha, wo, u)
            return LobeSample(wi=wi, pdf=pdf, delta=delta, label=LABEL_GLOSSY)
        wi, weight, pdf = np.empty((len(p), 3)), np.zeros((len(p), 3)), np.ones(len(p))
        d, s = np.flatnonzero(delta), np.flatnonzero(~delta)
        # Mirror rows: F at wo, none under the shading normal.
        wi[d] = wo[d] * _MIRROR_XY
        weight[d] = fresnel_color(p.take(d), np.clip(wo[d, 2], 0.0, 1.0)) * (wo[d, 2] > 0)[:, None]
        if len(s):
            wi[s], _, pdf[s] = microfacet.sample_reflection(p.alpha[s], wo[s], u[s])
        return LobeSample(wi=wi, pdf=pdf, delta=delta, label=LABEL_GLOSSY, weight=weight)

    def drop_caustics(self, p, reflection, refraction):
        return reflection  # Cycles makes no glossy or metallic closure

    def blur(self, p, min_alpha):
        blur(p, min_alpha, self.is_delta)

    def layer_weight(self, p, wo):
        return specular_layer_weight(p, wo)

    def stores_photons(self, m, lobe, min_roughness):
        return m.lobe_roughness[lobe] >= min_roughness

    def analysis_albedo(self, m, lobe, color, min_roughness):
        a = np.maximum(mean_albedo(m, lobe, color), 0.0)
        sharp = m.lobe_roughness[lobe] < min_roughness
        return {"glossy": np.where(sharp, 0.0, a), "specular": np.where(sharp, a, 0.0)}
