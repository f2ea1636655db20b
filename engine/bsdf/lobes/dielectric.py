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
refraction colour, or without one the reflection tint times the mean remapped Fresnel).

Coloured Fresnel (Cycles' generalised Schlick on glass): rows of FRESNEL_DIELECTRIC (Principled
transmission) reflect the exact Fresnel remapped to F0 = F0(ior) x their Specular Tint, rows
with a thin film (Glass, Principled) its iridescent Fresnel F_c (engine/bsdf/thin_film.py, the
film's index relative to wo's side); they reflect F_c x tint and refract (1 - F_c) x colour.
The branch is still chosen with the exact Fresnel F (unbiased: the colours are divided by F
and 1 - F). Refraction-only rows (Refraction BSDF) never reflect. Rows of DIST_BECKMANN (Glass
and Refraction BSDF) use the Beckmann distribution (dielectric.BECKMANN)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...scene import DIST_BECKMANN, DIST_MULTI_GGX, FRESNEL_DIELECTRIC, LOBE_DIELECTRIC, RAY_GLOSSY, RAY_TRANSMIT
from .. import dielectric, fresnel, microfacet, multiscatter, thin_film
from . import inputs
from .base import CLASS_GLOSSY, CLASS_TRANSMISSION, LABEL_GLOSSY, LABEL_TRANSMIT, LobeSample, SurfaceLobe, SurfaceParams
from .microfacet import blur, specular_layer_weight

_MIRROR_Z = np.array([1.0, 1.0, -1.0])  # the local frame seen from the other side


@dataclass
class DielectricParams(SurfaceParams):
    """tint (K,3) of reflection (colour: of refraction); roughness (K,); alpha (K,) GGX;
    ior (K,) n_inside / n_outside; inside (K,) bool: wo behind the winding normal; multi
    (K,) bool: DIST_MULTI_GGX; f0_tint (K,3) the remapped Fresnel's F0 tint (1: the exact
    Fresnel); film, film_ior (K,) the thin film; coloured (K,) bool: rows of a coloured
    Fresnel (F0 tint or film); refract_only (K,) bool or None (no such row); beckmann (K,)
    bool or None (no such row): DIST_BECKMANN."""

    tint: np.ndarray
    roughness: np.ndarray
    alpha: np.ndarray
    ior: np.ndarray
    inside: np.ndarray
    multi: np.ndarray
    f0_tint: np.ndarray
    film: np.ndarray
    film_ior: np.ndarray
    coloured: np.ndarray
    refract_only: np.ndarray | None
    beckmann: np.ndarray | None


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


def fresnel_colours(p: DielectricParams, cos_oh: np.ndarray, eta_rel: np.ndarray, outside: np.ndarray):
    """(reflected F_c tint, refracted (1 - F_c) colour) (K,3) of coloured rows at cosine cos_oh
    (K,) with the microfacet normal, eta_rel (K,) across the interface from wo's side, outside
    (K,) bool: wo outside the object (the film's index is relative to wo's side)."""
    f0 = np.clip(fresnel.f0_from_ior(eta_rel)[:, None] * p.f0_tint, 0.0, 1.0)
    F = fresnel.dielectric_remapped(f0, cos_oh, eta_rel)
    r = np.flatnonzero(p.film > thin_film.CUTOFF)
    if len(r):
        n_f = np.where(outside[r], p.film_ior[r], p.film_ior[r] / p.ior[r])
        Fi = thin_film.over_dielectric(cos_oh[r], p.film[r], n_f, eta_rel[r])
        F[r] = thin_film.scale_to_f0(Fi, f0[r], eta_rel[r])
    return F * p.tint, (1.0 - F) * p.color


def _colour_factors(p, cos_oh, eta_rel, outside, reflect):
    """Factors (K,3) of coloured rows' white f (which holds F or 1 - F): F_c tint / F where
    they reflect, (1 - F_c) colour / (1 - F) where they refract."""
    R, T = fresnel_colours(p, cos_oh, eta_rel, outside)
    F = fresnel.dielectric(cos_oh, eta_rel)[:, None]
    return np.where(reflect[:, None], np.divide(R, F, out=np.zeros_like(R), where=F > 0.0),
                    np.divide(T, 1.0 - F, out=np.zeros_like(T), where=F < 1.0))


def _outward(p: DielectricParams) -> np.ndarray:
    """(K,3) factors taking the local frame to the one whose z points out of the object."""
    return np.where(p.inside[:, None], _MIRROR_Z, 1.0)


def _sample_smooth(p, wo, wo_o, out, u_branch):
    """Smooth rows: (wi, weight F tint / pmf or (1 - F) colour / (eta_rel^2 pmf), pmf)."""
    wi_o, w, pmf, reflected = dielectric.sample_smooth(p.ior, wo_o, u_branch, p.refract_only)
    colour = np.where(reflected[:, None], p.tint, p.color)
    c = np.flatnonzero(p.coloured)
    if len(c):
        outside = wo_o[c, 2] > 0
        eta_rel = np.where(outside, p.ior[c], 1.0 / p.ior[c])
        colour[c] = _colour_factors(p.take(c), np.abs(wo_o[c, 2]), eta_rel, outside, reflected[c])
    weight = w * colour * (wo[:, 2] > 0)[:, None]
    return wi_o * out, weight, pmf


def _by_distribution(p, fn, *rows_args):
    """fn(alpha, ior, *args, refract_only, dist) over p's rows, per distribution; rows_args
    (K, ...) arrays; returns fn's outputs (a tuple or one array) for all rows."""
    if p.beckmann is None:
        return fn(p.alpha, p.ior, *rows_args, p.refract_only)
    parts = []
    for dist, r in ((dielectric.GGX, np.flatnonzero(~p.beckmann)), (dielectric.BECKMANN, np.flatnonzero(p.beckmann))):
        if len(r):
            only = None if p.refract_only is None else p.refract_only[r]
            parts.append((r, fn(p.alpha[r], p.ior[r], *(a[r] for a in rows_args), only, dist)))
    one = not isinstance(parts[0][1], tuple)
    outs = [np.empty((len(p),) + np.shape(v)[1:]) for v in ((parts[0][1],) if one else parts[0][1])]
    for r, v in parts:
        for o, x in zip(outs, (v,) if one else v):
            o[r] = x
    return outs[0] if one else tuple(outs)


def _sample_rough(p, wo, wo_o, out, u, u_branch):
    """Rough rows: (wi, pdf), pdf 0 for wo under the shading normal."""
    wi_o, _, pdf = _by_distribution(p, dielectric.sample_rough, wo_o, u, u_branch)
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
        tint = inputs.tint(m, lobe, color, src)
        f0_tint = np.ones((len(lobe), 3))
        remapped = m.lobe_fresnel[lobe] == FRESNEL_DIELECTRIC
        if remapped.any():  # the tint is the Fresnel's F0 tint; reflection itself is untinted
            f0_tint[remapped], tint = tint[remapped], np.where(remapped[:, None], 1.0, tint)
        film, film_ior = inputs.film(m, lobe, src)
        refract_only = m.lobe_refract_only[lobe]
        beckmann = m.lobe_distribution[lobe] == DIST_BECKMANN
        return DielectricParams(color=color, delta=dielectric.is_delta(alpha, ior), tint=tint,
                                roughness=roughness, alpha=alpha, ior=ior, inside=inside[point],
                                multi=m.lobe_distribution[lobe] == DIST_MULTI_GGX, f0_tint=f0_tint, film=film,
                                film_ior=film_ior, coloured=remapped | (film > thin_film.CUTOFF),
                                refract_only=refract_only if refract_only.any() else None,
                                beckmann=beckmann if beckmann.any() else None)

    def is_delta(self, p):
        return dielectric.is_delta(p.alpha, p.ior)

    def _reflected_refracted(self, p, wo):
        """(reflected, refracted) albedo parts (K,3) at wo, before the energy compensation."""
        cos = np.abs(wo[:, 2])
        F = fresnel.dielectric(cos, p.ior)[:, None]
        R, T = F * p.tint, (1.0 - F) * p.color
        c = np.flatnonzero(p.coloured)
        if len(c):
            outside = (wo[c, 2] > 0) != p.inside[c]
            R[c], T[c] = fresnel_colours(p.take(c), cos[c], np.where(outside, p.ior[c], 1.0 / p.ior[c]), outside)
        if p.refract_only is not None:
            R[p.refract_only] = 0.0
        return R, T

    def albedo(self, p, wo):
        R, T = self._reflected_refracted(p, wo)
        a = R + T
        r, _, darkening = energy(p, wo)
        if len(r):
            a[r] *= darkening
        return a

    def eval(self, p, wo, wi):
        out = _outward(p)
        wo_o, wi_o = wo * out, wi * out
        reflected = ((wi[:, 2] > 0) == (wo[:, 2] > 0))[:, None]
        tint = np.where(reflected, p.tint, p.color)
        c = np.flatnonzero(p.coloured)
        if len(c):
            cos_oh, eta_rel, reflect = dielectric.half_cosine(p.ior[c], wo_o[c], wi_o[c])
            tint[c] = _colour_factors(p.take(c), cos_oh, eta_rel, wo_o[c, 2] > 0, reflect)
        f = _by_distribution(p, dielectric.eval_rough, wo_o, wi_o) * tint * (wo[:, 2:3] > 0)
        r, scale, _ = energy(p, wo, wi)
        if len(r):
            f[r] *= scale
        return f, np.where(wo[:, 2] > 0, _by_distribution(p, dielectric.pdf_rough, wo_o, wi_o), 0.0)

    def pdf(self, p, wo, wi):
        out = _outward(p)
        return np.where(wo[:, 2] > 0, _by_distribution(p, dielectric.pdf_rough, wo * out, wi * out), 0.0)

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
        reflected = weight * self._reflected_refracted(p, wo)[0]
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
