"""The glass lobe (Glass and Refraction BSDF, Principled transmission): reflection and
refraction at a dielectric interface of relative IOR ior, rough (GGX, Walter et al. 2007) or
smooth (formulas: engine/bsdf/dielectric.py). Reflection is tinted by tint, refraction by
the colour.

The formulas want z pointing out of the object: at points seen from inside (wo behind the
triangle's winding normal; the shading frame is on wo's side) the local frame is mirrored,
so that wo.z < 0 and eta becomes 1 / eta. wo under the shading normal (smooth-normal
silhouettes) has no glass lobe, as in Cycles.

Rows of DIST_MULTI_GGX are scaled by Cycles' energy compensation for glass
(engine/bsdf/multiscatter.py: the glass tables at the IOR relative to wo's side, Fss the
refraction colour, or without one the reflection tint times the mean remapped Fresnel)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...scene import DIST_MULTI_GGX, LOBE_DIELECTRIC, RAY_GLOSSY, RAY_TRANSMIT
from .. import dielectric, fresnel, microfacet, multiscatter
from . import inputs
from .base import CLASS_GLOSSY, CLASS_TRANSMISSION, LABEL_GLOSSY, LABEL_TRANSMIT, LobeSample, SurfaceLobe, SurfaceParams
from .microfacet import blur, specular_layer_weight

_MIRROR_Z = np.array([1.0, 1.0, -1.0])  # the local frame seen from the other side


@dataclass
class DielectricParams(SurfaceParams):
    """tint (K,3) of reflection (colour: of refraction); roughness (K,); alpha (K,) GGX;
    ior (K,) n_inside / n_outside; inside (K,) bool: wo behind the winding normal; multi
    (K,) bool: DIST_MULTI_GGX."""

    tint: np.ndarray
    roughness: np.ndarray
    alpha: np.ndarray
    ior: np.ndarray
    inside: np.ndarray
    multi: np.ndarray


def energy(p: DielectricParams, wo: np.ndarray, wi=None):
    """(rows (R,) of DIST_MULTI_GGX, their (scale, darkening) (R,3)) at the viewing direction:
    wo, or wi (where given) for the adjoint, the IOR relative to its side."""
    r = np.flatnonzero(p.multi)
    if not len(r):
        return r, None, None
    view = (wi if p.adjoint and wi is not None else wo)[r]
    q, mu = p.take(r), np.clip(np.abs(view[:, 2]), 0.0, 1.0)
    eta = np.where(q.inside ^ (view[:, 2] < 0), 1.0 / q.ior, q.ior)
    Fss = np.maximum(q.color, 0.0)
    dark = ~np.any(Fss > 0.0, axis=1)  # refraction left out: Cycles takes the reflection's
    if dark.any():
        Fss[dark] = q.tint[dark] * multiscatter.fss_remapped(fresnel.f0_from_ior(eta[dark])[:, None], eta[dark])
    scale, darkening = multiscatter.factor(multiscatter.glass_E(q.roughness, mu, eta),
                                           multiscatter.glass_E_avg(q.roughness, eta), Fss)
    return r, scale, darkening


def _outward(p: DielectricParams) -> np.ndarray:
    """(K,3) factors taking the local frame to the one whose z points out of the object."""
    return np.where(p.inside[:, None], _MIRROR_Z, 1.0)


def _sample_smooth(p, wo, wo_o, out, u_branch):
    """Smooth rows: (wi, weight F tint / pmf or (1 - F) colour / (eta_rel^2 pmf), pmf)."""
    wi_o, w, pmf, reflected = dielectric.sample_smooth(p.ior, wo_o, u_branch)
    weight = w * np.where(reflected[:, None], p.tint, p.color) * (wo[:, 2] > 0)[:, None]
    return wi_o * out, weight, pmf


def _sample_rough(p, wo, wo_o, out, u, u_branch):
    """Rough rows: (wi, pdf), pdf 0 for wo under the shading normal."""
    wi_o, _, pdf = dielectric.sample_rough(p.alpha, p.ior, wo_o, u, u_branch)
    return wi_o * out, np.where(wo[:, 2] > 0, pdf, 0.0)


class Dielectric(SurfaceLobe):
    kind = LOBE_DIELECTRIC
    rays = RAY_GLOSSY | RAY_TRANSMIT  # left out only for lights invisible to both (Cycles)
    reflection_class, transmission_class = CLASS_GLOSSY, CLASS_TRANSMISSION
    needs_side = True

    def parameters(self, m, lobe, point, src, inside) -> DielectricParams:
        color = inputs.color(m, lobe, point, src)
        roughness = inputs.roughness(m, lobe, point, src)
        alpha = microfacet.alpha_from_roughness(roughness)
        ior = inputs.ior(m, lobe, src)
        return DielectricParams(color=color, delta=dielectric.is_delta(alpha, ior), tint=inputs.tint(m, lobe, color, src),
                                roughness=roughness, alpha=alpha, ior=ior, inside=inside[point],
                                multi=m.lobe_distribution[lobe] == DIST_MULTI_GGX)

    def is_delta(self, p):
        return dielectric.is_delta(p.alpha, p.ior)

    def albedo(self, p, wo):
        F = fresnel.dielectric(np.abs(wo[:, 2]), p.ior)[:, None]
        a = F * p.tint + (1.0 - F) * p.color
        r, _, darkening = energy(p, wo)
        if len(r):
            a[r] *= darkening
        return a

    def eval(self, p, wo, wi):
        out = _outward(p)
        wo_o, wi_o = wo * out, wi * out
        reflected = ((wi[:, 2] > 0) == (wo[:, 2] > 0))[:, None]
        tint = np.where(reflected, p.tint, p.color) * (wo[:, 2:3] > 0)
        f = dielectric.eval_rough(p.alpha, p.ior, wo_o, wi_o) * tint
        r, scale, _ = energy(p, wo, wi)
        if len(r):
            f[r] *= scale
        return f, np.where(wo[:, 2] > 0, dielectric.pdf_rough(p.alpha, p.ior, wo_o, wi_o), 0.0)

    def pdf(self, p, wo, wi):
        out = _outward(p)
        return np.where(wo[:, 2] > 0, dielectric.pdf_rough(p.alpha, p.ior, wo * out, wi * out), 0.0)

    def sample(self, p, wo, u, u_branch) -> LobeSample:
        out = _outward(p)
        wo_o = wo * out
        # eta_rel = n(wi side) / n(wo side) of a refraction; wo_o.z > 0: wo outside.
        eta2 = np.where(wo_o[:, 2] > 0, p.ior, 1.0 / p.ior) ** 2
        smooth = p.delta
        if smooth.all():
            wi, weight, pdf = _sample_smooth(p, wo, wo_o, out, u_branch)
        elif not smooth.any():
            (wi, pdf), weight = _sample_rough(p, wo, wo_o, out, u, u_branch), None
        else:
            wi, weight, pdf = np.empty((len(p), 3)), np.zeros((len(p), 3)), np.empty(len(p))
            d, s = np.flatnonzero(smooth), np.flatnonzero(~smooth)
            wi[d], weight[d], pdf[d] = _sample_smooth(p.take(d), wo[d], wo_o[d], out[d], u_branch[d])
            wi[s], pdf[s] = _sample_rough(p.take(s), wo[s], wo_o[s], out[s], u[s], u_branch[s])
        if weight is not None:
            r, scale, _ = energy(p, wo, wi)
            if len(r):
                weight[r] *= scale
        label = np.where(wi[:, 2] * wo[:, 2] < 0, LABEL_TRANSMIT, LABEL_GLOSSY)
        return LobeSample(wi=wi, pdf=pdf, delta=smooth, label=label, weight=weight, eta2=eta2)

    def drop_caustics(self, p, reflection, refraction):
        # Cycles' Glass keeps a zero reflection or transmission tint.
        p.tint[reflection] = 0.0
        p.color[refraction] = 0.0
        return None

    def blur(self, p, min_alpha):
        blur(p, min_alpha, self.is_delta)

    def layer_weight(self, p, wo):
        return specular_layer_weight(p, wo)

    def albedo_parts(self, p, wo, weight, estimate):
        # F tint reflects (glossy), (1 - F) colour refracts (transmission).
        F = fresnel.dielectric(np.abs(wo[:, 2]), p.ior)[:, None]
        reflected = weight * F * p.tint
        r, _, darkening = energy(p, wo)
        if len(r):
            reflected[r] *= darkening
        return [(CLASS_GLOSSY, reflected), (CLASS_TRANSMISSION, estimate - reflected)]

    def stores_photons(self, m, lobe, min_roughness):
        return m.lobe_roughness[lobe] >= min_roughness

    def analysis_albedo(self, m, lobe, color, min_roughness):
        # Glass passes or reflects almost all light whatever its tint: its weight.
        a = np.maximum(m.lobe_weight[lobe].mean(axis=1), 0.0)
        sharp = m.lobe_roughness[lobe] < min_roughness
        return {"glossy": np.where(sharp, 0.0, a), "specular": np.where(sharp, a, 0.0)}
