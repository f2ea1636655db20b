"""Dielectric interface (Glass / Refraction BSDF, Principled transmission): smooth and rough.

Local shading frame, z = the surface normal pointing *out of* the object, float64, one row per
shading point. `eta` (N,) or scalar is the object's relative IOR n_inside / n_outside; the
caller passes wo on its true geometric side, so wo.z < 0 means wo is inside the object. Below,
eta_rel = n(wi side) / n(wo side) for a refraction: eta when wo is outside, 1 / eta inside.

Radiance scaling: camera paths carry radiance, and radiance crossing an interface scales with
n^2, so refraction f and weight include 1 / eta_rel^2 (pbrt-v4 TransportMode::Radiance; Veach
1997 sec. 5.2): a camera ray refracting into glass of eta = 1.5 gets weight 1 / 2.25 (f holds
(1 - F) / 2.25, and the lobe probability 1 - F cancels). Cycles omits this factor (its BTDF is
Walter's as printed); for closed objects with camera and lights outside, the factors cancel
along every path (in 1 / eta^2, out eta^2, including next-event estimation from inside), so
images agree. They differ where a light or the camera is inside a refractive object.

Fresnel: exact dielectric (fresnel.dielectric) at the microfacet normal; the lobe is chosen
with probability F (reflect) / 1 - F (refract), as Cycles' glass (bsdf_microfacet.h
bsdf_microfacet_sample, pdf_reflect = F). Total internal reflection has F = 1: the sample
reflects, never NaN. Callers apply tints (Glass colour, Principled sqrt(base colour) on
transmission) on top of the returned f and weight.

Refraction only (Cycles' Refraction BSDF, `refract_only` rows): no reflection lobe; a
refraction of f (without the factor 1 - F) sampled with probability 1, none under total
internal reflection.

Rough: Walter, Marschner, Li, Torrance 2007, "Microfacet Models for Refraction through Rough
Surfaces" (eqs. 16-21), GGX with visible-normal sampling (microfacet.sample_vndf) and Cycles'
height-correlated G2 for both lobes; or (dist=BECKMANN: Cycles' Beckmann Glass and Refraction)
Beckmann's D and Cycles' G2 (engine/bsdf/beckmann.py), normals sampled from D(h) cos_h. Rows
with `is_delta(alpha, eta)` must use sample_smooth.
"""
import numpy as np

from . import beckmann, fresnel, microfacet
from ..vec import dot, normalize


class _GGX:
    """The distribution's D, G2, the density of the normals it samples and its sampler."""

    D, G2 = staticmethod(microfacet.D), staticmethod(microfacet.G2)

    @staticmethod
    def density(alpha, wo, h):
        """Visible normals: G1(wo) (wo.h) D(h) / wo.z (times wo.z: the caller divides)."""
        return microfacet.G1(alpha, wo) * dot(wo, h) * microfacet.D(alpha, h), wo[:, 2]

    @staticmethod
    def sample(alpha, wo, u):
        return microfacet.sample_vndf(alpha, wo, u)


class _Beckmann:
    D, G2 = staticmethod(beckmann.D), staticmethod(beckmann.G2)

    @staticmethod
    def density(alpha, wo, h):
        return beckmann.D(alpha, h) * h[:, 2], np.ones(len(h))

    @staticmethod
    def sample(alpha, wo, u):
        return beckmann.sample_normal(alpha, u)


GGX, BECKMANN = _GGX(), _Beckmann()

# Cycles refracts straight through (a delta) when |eta - 1| < 1e-4 (bsdf_microfacet_sample).
INDEX_MATCHED_TOLERANCE = 1e-4


def is_delta(alpha, eta):
    """(N,) bool: rows to sample with sample_smooth (mirror-like roughness or eta ~ 1)."""
    eta = np.asarray(eta, dtype=np.float64)
    return microfacet.is_delta(alpha) | (np.abs(eta - 1.0) < INDEX_MATCHED_TOLERANCE)


def _wo_side_up(eta, wo):
    """(sign (N,), eta_rel (N,), wo turned to +z): work as if wo were outside."""
    eta = np.broadcast_to(np.asarray(eta, dtype=np.float64), wo.shape[:1])
    inside = wo[:, 2] < 0.0
    sign = np.where(inside, -1.0, 1.0)
    return sign, np.where(inside, 1.0 / eta, eta), wo * sign[:, None]


def _refract(wo, h, cos_oh, cos_t, eta_rel):
    """Refract wo (N,3) through the (micro)normal h (wo.h = cos_oh > 0; cos_t < 0 from Fresnel)."""
    inv = 1.0 / eta_rel
    return -inv[:, None] * wo + (inv * cos_oh + cos_t)[:, None] * h


def _lobe_pmf(F, refract_only):
    """Probability (N,) of reflecting: F, or for refraction-only rows 0 (1 under total
    internal reflection, whose reflection then weighs nothing)."""
    if refract_only is None:
        return F
    return np.where(refract_only, np.where(F >= 1.0, 1.0, 0.0), F)


def sample_smooth(eta, wo, u_lobe, refract_only=None):
    """Sample the delta lobes of a smooth interface: (wi, weight (N,3), pdf (N,), reflected (N,)).

    Reflect with probability F, else refract (Snell). pdf is the chosen lobe's probability (a
    discrete pmf, not a density: delta samples never enter MIS). weight = f |cos| / pdf is 1
    for reflection and 1 / eta_rel^2 for refraction (radiance scaling, see the module doc).
    """
    sign, eta_rel, wo_up = _wo_side_up(eta, wo)
    F, cos_t = fresnel.dielectric_with_cos_t(wo_up[:, 2], eta_rel)
    P = _lobe_pmf(F, refract_only)
    reflected = np.asarray(u_lobe, dtype=np.float64) < P
    n = np.array([0.0, 0.0, 1.0])
    wi_up = np.where(reflected[:, None], microfacet.reflect(wo_up, np.broadcast_to(n, wo.shape)),
                     _refract(wo_up, n, wo_up[:, 2], cos_t, eta_rel))
    weight = np.where(reflected, 1.0, 1.0 / (eta_rel * eta_rel))
    if refract_only is not None:
        weight = np.where(refract_only & reflected, 0.0, weight)
    pdf = np.where(reflected, P, 1.0 - P)
    return wi_up * sign[:, None], np.repeat(weight[:, None], 3, axis=1), pdf, reflected


def _rough_terms(alpha, eta_rel, wo, wi):
    """Shared geometry of eval/pdf for wo, wi in the wo-up frame.

    Returns (h, F, reflect, ok, jac) where h is the (generalised) half vector with h.z > 0,
    F the Fresnel reflectance at h, reflect (N,) whether wi is on wo's side, ok (N,) whether the
    pair is a valid configuration, and jac (N,) = |d omega_h / d omega_i| (Walter eqs. 14, 17).
    """
    reflect = wi[:, 2] > 0.0
    h_t = wo + eta_rel[:, None] * wi
    h_t = h_t * np.where(h_t[:, 2] < 0.0, -1.0, 1.0)[:, None]
    h = normalize(np.where(reflect[:, None], wo + wi, h_t))
    cos_oh = dot(wo, h)
    cos_ih = dot(wi, h)
    # Walter's sidedness: wo in front of the microfacet, wi behind it for a refraction.
    ok = (wo[:, 2] > 0.0) & (wi[:, 2] != 0.0) & (cos_oh > 0.0) & (reflect | (cos_ih < 0.0))
    F = fresnel.dielectric(cos_oh, eta_rel)
    # |wo + eta_rel wi|^2 = (wo.h + eta_rel wi.h)^2 for the generalised half vector.
    den_t = dot(h_t, h_t)
    jac_t = np.divide(eta_rel * eta_rel * np.abs(cos_ih), den_t, out=np.zeros(len(wo)),
                      where=den_t > 0.0)
    jac_r = np.divide(1.0, 4.0 * cos_oh, out=np.zeros(len(wo)), where=cos_oh > 0.0)
    return h, F, reflect, ok, np.where(reflect, jac_r, jac_t)


def half_cosine(eta, wo, wi):
    """(cos_oh (N,), eta_rel (N,), reflect (N,) bool) of the pair wo, wi (N,3): wo's cosine with
    the (generalised) half vector, the IOR across the interface from wo's side, and whether wi
    lies on wo's side (the frame of eval_rough)."""
    sign, eta_rel, wo_up = _wo_side_up(eta, wo)
    wi_up = wi * sign[:, None]
    reflect = wi_up[:, 2] > 0.0
    h = normalize(np.where(reflect[:, None], wo_up + wi_up, -(wo_up + eta_rel[:, None] * wi_up)))
    h = h * np.where(h[:, 2] < 0.0, -1.0, 1.0)[:, None]
    return dot(wo_up, h), eta_rel, reflect


def eval_rough(alpha, eta, wo, wi, refract_only=None, dist=GGX):
    """f (N,3) of the rough interface (white; multiply by tints), per unit solid angle.

    Reflection (wi on wo's side): F D G2 / (4 |cos_o cos_i|).
    Refraction: |wo.h wi.h| (1 - F) D G2 / (|cos_o cos_i| |wo + eta_rel wi|^2), i.e. Walter's
    BTDF divided by eta_rel^2 (radiance scaling). Satisfies f(wi, wo) = f(wo, wi) eta_rel^2
    (generalised reciprocity) for refraction and f(wi, wo) = f(wo, wi) for reflection.
    """
    sign, eta_rel, wo_up = _wo_side_up(eta, wo)
    wi_up = wi * sign[:, None]
    h, F, reflect, ok, jac = _rough_terms(alpha, eta_rel, wo_up, wi_up)
    dg = dist.D(alpha, h) * dist.G2(alpha, wo_up, wi_up)
    cos_oi = np.abs(wo_up[:, 2] * wi_up[:, 2])
    # Both lobes are lobe x D G2 (wo.h) jac / |cos_o cos_i|: (wo.h) jac is 1/4 for reflection
    # and eta_rel^2 |wo.h wi.h| / |wo + eta_rel wi|^2 for refraction.
    lobe = np.where(reflect, F, (1.0 - F) / (eta_rel * eta_rel))
    if refract_only is not None:
        lobe = np.where(refract_only, np.where(reflect | (F >= 1.0), 0.0, 1.0 / (eta_rel * eta_rel)), lobe)
    f = np.divide(lobe * dg * dot(wo_up, h) * jac, cos_oi, out=np.zeros(len(wo)),
                  where=ok & (cos_oi > 0.0))
    return np.repeat(f[:, None], 3, axis=1)


def pdf_rough(alpha, eta, wo, wi, refract_only=None, dist=GGX):
    """Solid-angle pdf (N,) of sample_rough at wi: lobe probability x density of h x |dh / dwi|."""
    sign, eta_rel, wo_up = _wo_side_up(eta, wo)
    h, F, reflect, ok, jac = _rough_terms(alpha, eta_rel, wo_up, wi * sign[:, None])
    P = _lobe_pmf(F, refract_only)
    return _pdf(alpha, wo_up, h, np.where(reflect, P, 1.0 - P), jac, ok, dist)


def _pdf(alpha, wo_up, h, lobe, jac, ok, dist):
    """lobe (N,) x the density of the sampled normal h x jac (N,)."""
    density, den = dist.density(alpha, wo_up, h)
    return np.divide(lobe * density * jac, den, out=np.zeros(len(h)), where=ok & (den > 0.0))


def sample_rough(alpha, eta, wo, u, u_lobe, refract_only=None, dist=GGX):
    """Sample the rough interface: (wi (N,3), weight (N,3) = f |cos_i| / pdf, pdf (N,)).

    h from the visible normals of wo, then reflect with probability F(wo.h), else refract
    through h. weight = G2 / G1(wo) for reflection, G2 / (G1(wo) eta_rel^2) for refraction.
    A wi on the wrong side for its lobe gets weight 0 and pdf 0 (no redraw).
    """
    sign, eta_rel, wo_up = _wo_side_up(eta, wo)
    h = dist.sample(alpha, wo_up, u)
    cos_oh = dot(wo_up, h)
    F, cos_t = fresnel.dielectric_with_cos_t(cos_oh, eta_rel)
    P = _lobe_pmf(F, refract_only)
    reflect = np.asarray(u_lobe, dtype=np.float64) < P
    wi_up = np.where(reflect[:, None], microfacet.reflect(wo_up, h),
                     _refract(wo_up, h, cos_oh, cos_t, eta_rel))
    ok = (wo_up[:, 2] > 0.0) & (cos_oh > 0.0) & np.where(reflect, wi_up[:, 2] > 0.0,
                                                          wi_up[:, 2] < 0.0)
    h_t = wo_up + eta_rel[:, None] * wi_up
    den_t = dot(h_t, h_t)
    jac_t = np.divide(eta_rel * eta_rel * np.abs(dot(wi_up, h)), den_t, out=np.zeros(len(h)),
                      where=den_t > 0.0)
    jac = np.where(reflect, np.divide(1.0, 4.0 * cos_oh, out=np.zeros(len(h)), where=ok), jac_t)
    pdf = _pdf(alpha, wo_up, h, np.where(reflect, P, 1.0 - P), jac, ok, dist)
    if dist is GGX:
        g1 = microfacet.G1(alpha, wo_up)
        ratio = np.divide(microfacet.G2(alpha, wo_up, wi_up), g1, out=np.zeros(len(h)),
                          where=ok & (pdf > 0.0) & (g1 > 0.0))
        weight = np.where(reflect, ratio, ratio / (eta_rel * eta_rel))
    else:
        f = eval_rough(alpha, eta_rel, wo_up, wi_up, refract_only, dist)[:, 0]
        weight = np.divide(f * np.abs(wi_up[:, 2]), pdf, out=np.zeros(len(h)), where=pdf > 0.0)
    if refract_only is not None:
        weight = np.where(refract_only & reflect, 0.0, weight)
    return wi_up * sign[:, None], np.repeat(weight[:, None], 3, axis=1), pdf
