"""The GGX reflection lobe (Glossy BSDF, Metallic, Principled metallic and specular layers):
F D G2 / (4 cos_o cos_i), a perfect mirror when smooth (formulas: engine/bsdf/microfacet.py).

Its Fresnel colour F per FRESNEL_* model (Cycles' svm/closure.h): none (F = colour, Glossy
BSDF), F82-tint conductor (f0 = colour, edge tint = tint; Principled metallic), the exact
dielectric Fresnel of ior remapped to F0(ior) tint .. 1 (Principled specular) and the
Principled coat: the exact dielectric Fresnel of ior times the colour (the coat weight, which
Cycles' coat closure carries in its weight), Coat Tint (tint) colouring what lies under it.

Rows of DIST_MULTI_GGX (Blender's default distribution) are scaled by Cycles' energy
compensation (engine/bsdf/multiscatter.py) with the mean Fresnel Fss of their model, the factor
of wo applied to eval, to mirror samples' weights and to the albedo estimates. Rows of
DIST_BECKMANN (Glossy and Metallic) use the Beckmann distribution (engine/bsdf/beckmann.py),
rows of DIST_ASHIKHMIN_SHIRLEY (Glossy) Cycles' Ashikhmin-Shirley lobe
(engine/bsdf/ashikhmin_shirley.py, its own alpha clamp and mirror threshold).

Anisotropy (GGX, Multiscatter GGX, Beckmann): rows whose programs give an aspect s and a
tangent have alpha_x = alpha / s along the tangent and alpha_y = alpha s across it, each at most
1 (Cycles' bsdf_microfacet_ggx_setup), and use engine/bsdf/anisotropic.py; a mirror when
alpha_x alpha_y <= 2e-10; the energy compensation and the layering tables read the roughness
(alpha_x alpha_y)^(1/4), as Cycles'. FRESNEL_CONDUCTOR rows (the Metallic BSDF's Physical
Conductor) take the exact conductor Fresnel of n = colour, k = tint. A thin film (thickness,
index) replaces the F82, conductor or dielectric Fresnel by its iridescent one
(engine/bsdf/thin_film.py) as Cycles' microfacet_fresnel does; Cycles' estimate of such a
lobe's albedo is that Fresnel at wo (no table), which the layering then takes."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...scene import (DIST_ASHIKHMIN_SHIRLEY, DIST_BECKMANN, DIST_MULTI_GGX, FRESNEL_COAT, FRESNEL_CONDUCTOR,
                      FRESNEL_DIELECTRIC, FRESNEL_F82, LOBE_MICROFACET, RAY_GLOSSY)
from ...vec import dot, max3, normalize
from .. import anisotropic, ashikhmin_shirley, beckmann, fresnel, layering, microfacet, multiscatter, thin_film
from . import inputs
from .base import CLASS_GLOSSY, LABEL_GLOSSY, LobeSample, SurfaceLobe, SurfaceParams, mean_albedo

_MIRROR_XY = np.array([-1.0, -1.0, 1.0])  # reflection about the normal
# The formulas of each MicrofacetParams.model: GGX (also Multiscatter GGX), Beckmann, A-S,
# and anisotropic GGX and Beckmann.
MODEL_GGX, MODEL_BECKMANN, MODEL_ASHIKHMIN, MODEL_GGX_ANISO, MODEL_BECKMANN_ANISO = 0, 1, 2, 3, 4
_MODELS = (microfacet, beckmann, ashikhmin_shirley, anisotropic.GGX_ANISO, anisotropic.BECKMANN_ANISO)
_COS_82 = 1.0 / 7.0


def _groups(p):
    """[(formula module, its rows (R,) or None for all rows, their alpha: (R,) or, for the
    anisotropic models, (R,4) = (alpha_x, alpha_y, tangent azimuth's cos, sin))]."""
    model = p.model
    if not model.any():
        return [(microfacet, None, p.alpha)]
    out = []
    for k in np.unique(model):
        r = np.flatnonzero(model == k)
        a = p.alpha[r] if k < MODEL_GGX_ANISO else np.column_stack([p.alpha[r], p.alpha_y[r], p.azimuth[r]])
        out.append((_MODELS[k], r, a))
    return out


@dataclass
class MicrofacetParams(SurfaceParams):
    """tint (K,3); roughness (K,) Blender's ((alpha_x alpha_y)^(1/4) where anisotropic); alpha
    (K,) GGX (roughness^2, or Filter Glossy's; alpha_x where anisotropic); alpha_y (K,) and
    azimuth (K,2) the tangent's (cos, sin) in the shading frame (used by the anisotropic
    models); ior (K,); fresnel (K,) FRESNEL_*; multi (K,) bool: DIST_MULTI_GGX; model (K,)
    int8 MODEL_* (the formulas of the row's distribution); film, film_ior (K,) the thin film
    (thickness nm, index)."""

    tint: np.ndarray
    roughness: np.ndarray
    alpha: np.ndarray
    alpha_y: np.ndarray
    azimuth: np.ndarray
    ior: np.ndarray
    fresnel: np.ndarray
    multi: np.ndarray
    model: np.ndarray
    film: np.ndarray
    film_ior: np.ndarray


def fresnel_color(p: MicrofacetParams, cos: np.ndarray) -> np.ndarray:
    """Fresnel colour F (K,3) at cosines cos (K,) between wo and the microfacet normal."""
    F = p.color.copy()  # FRESNEL_NONE: the Glossy colour
    film = p.film > thin_film.CUTOFF
    r = np.flatnonzero(p.fresnel == FRESNEL_F82)
    if len(r):
        F[r] = fresnel.f82_tint(p.color[r], np.minimum(p.tint[r], 1.0), cos[r])
    r = np.flatnonzero(p.fresnel == FRESNEL_DIELECTRIC)
    if len(r):
        eta = p.ior[r]
        F[r] = fresnel.dielectric_remapped(fresnel.f0_from_ior(eta)[:, None] * p.tint[r], cos[r], eta)
    r = np.flatnonzero(p.fresnel == FRESNEL_CONDUCTOR)
    if len(r):
        F[r] = fresnel.conductor(cos[r], p.color[r], p.tint[r])
    r = np.flatnonzero(p.fresnel == FRESNEL_COAT)
    if len(r):
        F[r] = p.color[r] * fresnel.dielectric(cos[r], p.ior[r])[:, None]
    if film.any():
        _iridescent(p, cos, np.flatnonzero(film), F)
    return F


def _iridescent(p, cos, rows, F):
    """F[rows] of rows with a thin film: over the conductor (F82 through the n, k it stands
    for) or the dielectric (then scaled to the specular's F0)."""
    fr, c, d, n_f = p.fresnel[rows], cos[rows], p.film[rows], p.film_ior[rows]
    r = np.flatnonzero(fr == FRESNEL_F82)
    if len(r):
        f0 = p.color[rows[r]]
        g = fresnel.f82(f0, fresnel.f82_b(f0, np.minimum(p.tint[rows[r]], 1.0)), np.full(len(r), _COS_82))
        n, k = thin_film.nk_from_f82(f0, g)
        F[rows[r]] = thin_film.over_conductor(c[r], d[r], n_f[r], n, k, F82=g)
    r = np.flatnonzero(fr == FRESNEL_CONDUCTOR)
    if len(r):
        F[rows[r]] = thin_film.over_conductor(c[r], d[r], n_f[r], p.color[rows[r]], p.tint[rows[r]])
    r = np.flatnonzero(fr == FRESNEL_DIELECTRIC)
    if len(r):
        eta = p.ior[rows[r]]
        f0 = np.clip(fresnel.f0_from_ior(eta)[:, None] * p.tint[rows[r]], 0.0, 1.0)
        F[rows[r]] = thin_film.scale_to_f0(thin_film.over_dielectric(c[r], d[r], n_f[r], eta), f0, eta)


def mean_fresnel(p: MicrofacetParams) -> np.ndarray:
    """Fss (K,3): the mean Fresnel Cycles' energy compensation takes per model."""
    Fss = np.maximum(p.color, 0.0)  # FRESNEL_NONE: the Glossy colour
    r = np.flatnonzero(p.fresnel == FRESNEL_F82)
    if len(r):
        f0 = np.clip(p.color[r], 0.0, 1.0)
        Fss[r] = multiscatter.fss_f82(f0, fresnel.f82_b(f0, np.minimum(p.tint[r], 1.0)))
    r = np.flatnonzero(p.fresnel == FRESNEL_DIELECTRIC)
    if len(r):
        eta = p.ior[r]
        Fss[r] = multiscatter.fss_remapped(fresnel.f0_from_ior(eta)[:, None] * p.tint[r], eta)
    r = np.flatnonzero(p.fresnel == FRESNEL_CONDUCTOR)
    if len(r):
        Fss[r] = fresnel.conductor_fss(p.color[r], p.tint[r])
    r = np.flatnonzero(p.fresnel == FRESNEL_COAT)
    if len(r):  # the weight (colour) is no part of the Fresnel
        Fss[r] = multiscatter.fss_dielectric(p.ior[r])[:, None]
    return Fss


def _anisotropic(p: MicrofacetParams, aspect: np.ndarray, azimuth: np.ndarray) -> None:
    """Rows of aspect != 1 (GGX and Beckmann) become anisotropic: alpha_x = alpha / aspect,
    alpha_y = alpha aspect, each at most 1; their roughness the tables read (alpha_x
    alpha_y)^(1/4)."""
    r = np.flatnonzero((aspect != 1.0) & ((p.model == MODEL_GGX) | (p.model == MODEL_BECKMANN)))
    if not len(r):
        return
    ax, ay = np.minimum(p.alpha[r] / aspect[r], 1.0), np.minimum(p.alpha[r] * aspect[r], 1.0)
    p.alpha, p.alpha_y, p.azimuth = p.alpha.copy(), p.alpha_y.copy(), azimuth
    p.alpha[r], p.alpha_y[r] = ax, ay
    p.roughness = p.roughness.copy()
    p.roughness[r] = np.sqrt(np.sqrt(ax * ay))
    p.model = p.model.copy()
    p.model[r] = np.where(p.model[r] == MODEL_GGX, MODEL_GGX_ANISO, MODEL_BECKMANN_ANISO)


def energy(p: MicrofacetParams, wo: np.ndarray, wi=None):
    """(rows (R,) of DIST_MULTI_GGX, their (scale, darkening) (R,3)) at the viewing direction:
    wo, or wi (where given) for the adjoint."""
    r = np.flatnonzero(p.multi)
    if not len(r):
        return r, None, None
    view = wi if p.adjoint and wi is not None else wo
    q, mu = p.take(r), np.clip(view[r, 2], 0.0, 1.0)
    scale, darkening = multiscatter.factor(multiscatter.E(q.roughness, mu), multiscatter.E_avg(q.roughness),
                                           mean_fresnel(q))
    return r, scale, darkening


def specular_layer_weight(p, wo: np.ndarray, darkening=None) -> np.ndarray:
    """(K,) weight a dielectric specular layer (F0 = F0(ior) tint, roughness, ior) leaves to
    the lobes under it: Cycles' albedo estimate from its table (engine/bsdf/layering.py), times
    the energy compensation's darkening (K,3) where given."""
    f0 = fresnel.f0_from_ior(p.ior)[:, None] * p.tint
    return layering.base_weight(f0, p.roughness, wo[:, 2], p.ior, darkening)


def coat_layer_weight(p, wo: np.ndarray, darkening=None) -> np.ndarray:
    """(K,3) weight a coat leaves to the lobes under it (Cycles' svm/closure.h Principled):
    1 - its albedo estimate w mix(F0(ior), 1, s) (the layering), times mix(1, tint^(1 / cos_t),
    w), Coat Tint absorbed along the refracted ray's path through a coat of unit thickness
    (cos_t the cosine of wo refracted into the coat); w the coat weight (the colour)."""
    w = p.color[:, 0]
    cos_o = np.clip(wo[:, 2], 0.0, 1.0)
    f0 = np.repeat(fresnel.f0_from_ior(p.ior)[:, None], 3, axis=1)
    s = layering.schlick_factor(p.roughness, cos_o, p.ior)[:, None]
    albedo = w[:, None] * (f0 * (1.0 - s) + s) * (1.0 if darkening is None else darkening)
    out = np.repeat(np.clip(1.0 - albedo.max(axis=1), 0.0, 1.0)[:, None], 3, axis=1)
    tinted = np.flatnonzero(np.any(p.tint != 1.0, axis=1))
    if len(tinted):
        eta = p.ior[tinted]
        cos_t = np.sqrt(np.maximum(1.0 - (1.0 - cos_o[tinted] ** 2) / (eta * eta), 1e-12))
        absorbed = np.maximum(p.tint[tinted], 0.0) ** (1.0 / cos_t)[:, None]
        out[tinted] *= 1.0 + w[tinted, None] * (absorbed - 1.0)
    return out


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
        dist = m.lobe_distribution[lobe]
        model = np.where(dist == DIST_BECKMANN, MODEL_BECKMANN,
                         np.where(dist == DIST_ASHIKHMIN_SHIRLEY, MODEL_ASHIKHMIN, MODEL_GGX)).astype(np.int8)
        a = np.flatnonzero(model == MODEL_ASHIKHMIN)
        if len(a):
            alpha[a] = ashikhmin_shirley.alpha(roughness[a])
        film, film_ior = inputs.film(m, lobe, src)
        k = len(lobe)
        p = MicrofacetParams(color=color, delta=np.zeros(k, bool), tint=inputs.tint(m, lobe, color, src),
                             roughness=roughness, alpha=alpha, alpha_y=alpha, azimuth=np.zeros((k, 2)),
                             ior=inputs.ior(m, lobe, src), fresnel=m.lobe_fresnel[lobe], multi=dist == DIST_MULTI_GGX,
                             model=model, film=film, film_ior=film_ior)
        aniso = inputs.anisotropy(point, src)
        if aniso is not None:
            _anisotropic(p, *aniso)
        p.delta = self.is_delta(p)
        return p

    def is_delta(self, p):
        delta = microfacet.is_delta(p.alpha)
        a = np.flatnonzero(p.model == MODEL_ASHIKHMIN)
        if len(a):
            delta[a] = ashikhmin_shirley.is_delta(p.alpha[a])
        a = np.flatnonzero(p.model >= MODEL_GGX_ANISO)
        if len(a):
            delta[a] = microfacet.is_delta(np.sqrt(p.alpha[a] * p.alpha_y[a]))
        return delta

    def albedo(self, p, wo):
        a = fresnel_color(p, np.clip(wo[:, 2], 0.0, 1.0))
        r, _, darkening = energy(p, wo)
        if len(r):
            a[r] *= darkening
        return a

    def eval(self, p, wo, wi):
        h = normalize(wo + wi)
        F = fresnel_color(p, np.clip(dot(wo, h), 0.0, 1.0))
        r, scale, _ = energy(p, wo, wi)
        if len(r):
            F[r] *= scale
        groups = _groups(p)
        if groups[0][1] is None:
            return microfacet.eval_reflection(p.alpha, wo, wi, F), microfacet.pdf_reflection(p.alpha, wo, wi)
        f, pdf = np.empty((len(p), 3)), np.empty(len(p))
        for model, r, a in groups:
            f[r] = model.eval_reflection(a, wo[r], wi[r], F[r])
            pdf[r] = model.pdf_reflection(a, wo[r], wi[r])
        return f, pdf

    def pdf(self, p, wo, wi):
        groups = _groups(p)
        if groups[0][1] is None:
            return microfacet.pdf_reflection(p.alpha, wo, wi)
        pdf = np.empty(len(p))
        for model, r, a in groups:
            pdf[r] = model.pdf_reflection(a, wo[r], wi[r])
        return pdf

    def _sample_rough(self, p, wo, u):
        """(wi, pdf) of rows that are not delta."""
        groups = _groups(p)
        if groups[0][1] is None:
            return microfacet.sample_reflection(p.alpha, wo, u)[::2]
        wi, pdf = np.empty((len(p), 3)), np.empty(len(p))
        for model, r, a in groups:
            wi[r], _, pdf[r] = model.sample_reflection(a, wo[r], u[r])
        return wi, pdf

    def sample(self, p, wo, u, u_branch) -> LobeSample:
        delta = p.delta
        if not delta.any():
            wi, pdf = self._sample_rough(p, wo, u)
            return LobeSample(wi=wi, pdf=pdf, delta=delta, label=LABEL_GLOSSY)
        wi, weight, pdf = np.empty((len(p), 3)), np.zeros((len(p), 3)), np.ones(len(p))
        d, s = np.flatnonzero(delta), np.flatnonzero(~delta)
        # Mirror rows: F at wo, none under the shading normal.
        wi[d] = wo[d] * _MIRROR_XY
        q = p.take(d)
        weight[d] = fresnel_color(q, np.clip(wo[d, 2], 0.0, 1.0)) * (wo[d, 2] > 0)[:, None]
        r, scale, _ = energy(q, wo[d])
        if len(r):
            weight[d[r]] *= scale
        if len(s):
            wi[s], pdf[s] = self._sample_rough(p.take(s), wo[s], u[s])
        return LobeSample(wi=wi, pdf=pdf, delta=delta, label=LABEL_GLOSSY, weight=weight)

    def drop_caustics(self, p, reflection, refraction):
        return reflection  # Cycles makes no glossy or metallic closure

    def blur(self, p, min_alpha):
        a = np.flatnonzero(p.model >= MODEL_GGX_ANISO)
        if len(a):  # Cycles' bsdf_microfacet_blur raises both alphas
            p.alpha_y = p.alpha_y.copy()
            p.alpha_y[a] = np.maximum(p.alpha_y[a], min_alpha[a])
        blur(p, min_alpha, self.is_delta)

    def layer_weight(self, p, wo):
        darkening = None
        r, _, dark = energy(p, wo)
        if len(r):
            darkening = np.ones((len(p), 3))
            darkening[r] = dark
        coat = p.fresnel == FRESNEL_COAT
        if coat.all():
            return coat_layer_weight(p, wo, darkening)
        w = specular_layer_weight(p, wo, darkening)
        f = np.flatnonzero(p.film > thin_film.CUTOFF)
        if len(f):  # Cycles' estimate: the iridescent Fresnel at wo
            a = fresnel_color(p.take(f), np.clip(wo[f, 2], 0.0, 1.0))
            if darkening is not None:
                a *= darkening[f]
            w[f] = np.clip(1.0 - max3(a), 0.0, 1.0)
        c = np.flatnonzero(coat)
        if len(c):
            w = np.repeat(w[:, None], 3, axis=1)
            w[c] = coat_layer_weight(p.take(c), wo[c], None if darkening is None else darkening[c])
        return w

    def stores_photons(self, m, lobe, min_roughness):
        return m.lobe_roughness[lobe] >= min_roughness

    def analysis_albedo(self, m, lobe, color, min_roughness):
        conductor = m.lobe_fresnel[lobe] == FRESNEL_CONDUCTOR  # colour and tint are n and k
        if conductor.any():
            n, k = color[conductor], m.lobe_tint[lobe[conductor]]
            color = color.copy()
            color[conductor] = fresnel.conductor(np.ones(len(n)), n, k)
        a = np.maximum(mean_albedo(m, lobe, color), 0.0)
        # A coat reflects its weight (the colour) times its mean Fresnel.
        a = np.where(m.lobe_fresnel[lobe] == FRESNEL_COAT, a * multiscatter.fss_dielectric(m.lobe_ior[lobe]), a)
        sharp = m.lobe_roughness[lobe] < min_roughness
        return {"glossy": np.where(sharp, 0.0, a), "specular": np.where(sharp, a, 0.0)}
