"""Isotropic Beckmann microfacet reflection as Cycles evaluates it (Glossy and Metallic BSDF
with the Beckmann distribution): F D G2 / (4 cos_o cos_i), local shading frame as in
engine/bsdf/microfacet.py (alpha = roughness^2; a mirror below the same threshold).

- D(h) = exp(-tan^2 / alpha^2) / (pi alpha^2 cos^4) (bsdf_microfacet.h bsdf_D).
- G2 = 1 / (1 + Lambda(wo) + Lambda(wi)) with Cycles' rational approximation of Beckmann's
  Lambda (Walter et al. 2007, below their eq. 27; bsdf_lambda_from_sqr_alpha_tan_n): 0 where
  a = 1 / (alpha tan) >= 1.6, else (1 - 1.259 a + 0.396 a^2) / (3.535 a + 2.181 a^2).
- Sampling: microfacet normals from D(h) cos_h (tan^2 = -alpha^2 log(1 - u), Walter et al.
  eq. 28), wi their mirror of wo; pdf D(h) cos_h / (4 wo.h), exact for this sampler. Cycles
  samples Beckmann's visible normals instead; both are unbiased estimators of the same f,
  which is what renders alike. A sample whose wi falls under the surface (or whose normal
  faces away from wo) is dropped with pdf 0.
"""
import numpy as np

from ..vec import dot, normalize
from .microfacet import reflect


def D(alpha, h):
    """Beckmann D(h) (N,) per unit solid angle of h; 0 for h.z <= 0."""
    a2 = np.asarray(alpha, np.float64) ** 2
    c2 = h[:, 2] * h[:, 2]
    ok = (h[:, 2] > 0.0) & (a2 * c2 > 0.0)
    tan2_a2 = np.divide(h[:, 0] * h[:, 0] + h[:, 1] * h[:, 1], a2 * c2, out=np.full(len(h), np.inf), where=ok)
    return np.divide(np.exp(-tan2_a2), np.pi * a2 * c2 * c2, out=np.zeros(len(h)), where=ok)


def Lambda(alpha, w):
    """Cycles' approximation of Beckmann's Lambda (N,) (depends on |w.z|)."""
    a2 = np.asarray(alpha, np.float64) ** 2
    z2 = w[:, 2] * w[:, 2]
    s = np.divide(a2 * (w[:, 0] * w[:, 0] + w[:, 1] * w[:, 1]), z2, out=np.full(len(w), np.inf), where=z2 > 0.0)
    return lambda_of(s)


def lambda_of(s):
    """Cycles' Lambda (K,) from s = alpha^2 tan^2 (K,) (bsdf_lambda_from_sqr_alpha_tan_n)."""
    a = 1.0 / np.sqrt(np.maximum(s, 0.39))
    lam = ((0.396 * a - 1.259) * a + 1.0) / ((2.181 * a + 3.535) * a)
    return np.where(s < 0.39, 0.0, lam)


def G2(alpha, wo, wi):
    return 1.0 / (1.0 + Lambda(alpha, wo) + Lambda(alpha, wi))


def eval_reflection(alpha, wo, wi, F):
    """f (N,3) = F D G2 / (4 cos_o cos_i); 0 unless both directions are above the surface."""
    den = 4.0 * wo[:, 2] * wi[:, 2]
    ok = (wo[:, 2] > 0.0) & (wi[:, 2] > 0.0) & (den > 0.0)
    h = normalize(wo + wi)
    s = np.divide(D(alpha, h) * G2(alpha, wo, wi), den, out=np.zeros(len(wo)), where=ok)
    return np.asarray(F, np.float64) * s[:, None]


def _pdf(alpha, wo, h, ok):
    cos_oh = dot(wo, h)
    return np.divide(D(alpha, h) * h[:, 2], 4.0 * cos_oh, out=np.zeros(len(h)), where=ok & (cos_oh > 0.0))


def pdf_reflection(alpha, wo, wi):
    """Solid-angle pdf (N,) of sample_reflection at wi."""
    ok = (wo[:, 2] > 0.0) & (wi[:, 2] > 0.0)
    return _pdf(alpha, wo, normalize(wo + wi), ok)


def sample_normal(alpha, u):
    """Microfacet normals h (N,3) of density D(h) cos_h from u (N,2) (Walter et al. eq. 28)."""
    alpha = np.broadcast_to(np.asarray(alpha, np.float64), u.shape[:1])
    tan2 = -alpha * alpha * np.log1p(-np.clip(u[:, 0], 0.0, 1.0 - 1e-16))
    cos = 1.0 / np.sqrt(1.0 + tan2)
    sin = np.sqrt(np.maximum(1.0 - cos * cos, 0.0))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([sin * np.cos(phi), sin * np.sin(phi), cos], axis=-1)


def sample_reflection(alpha, wo, u):
    """(wi (N,3), h (N,3), pdf (N,)): h from D(h) cos_h, wi = wo mirrored about it."""
    h = sample_normal(alpha, u)
    wi = reflect(wo, h)
    ok = (wo[:, 2] > 0.0) & (wi[:, 2] > 0.0)
    return wi, h, _pdf(alpha, wo, h, ok)
