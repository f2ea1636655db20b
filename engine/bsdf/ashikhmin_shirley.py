"""Isotropic Ashikhmin-Shirley reflection as Cycles evaluates it (Glossy BSDF with the
Ashikhmin-Shirley distribution; closure/bsdf_ashikhmin_shirley.h), local shading frame as in
engine/bsdf/microfacet.py.

Ashikhmin & Shirley 2000, "An Anisotropic Phong BRDF Model", without its Fresnel factor (the
colour stands for it, as in Cycles): with alpha = roughness^2 clamped to [1e-4, 1] and
n = 2 / alpha^2 - 2,

    f = (n + 1) / (8 pi) (h.z)^n / ((h.wo) max(cos_o, cos_i))

(the cosines and h.wo kept from 1e-6 as Cycles does). Sampled by h with density
(n + 1) / (2 pi) (h.z)^n, wi its mirror of wo: pdf (n + 1) (h.z)^n / (8 pi h.wo). A lobe with
alpha <= 1e-4 (roughness <= 0.01) is a mirror. A sample whose normal faces away from wo or
whose wi falls under the surface is dropped with pdf 0.
"""
import numpy as np

from ..vec import dot, normalize
from .microfacet import reflect

DELTA_ALPHA = 1e-4


def alpha(roughness):
    return np.clip(np.asarray(roughness, np.float64) ** 2, DELTA_ALPHA, 1.0)


def is_delta(alpha_):
    return np.asarray(alpha_) <= DELTA_ALPHA


def exponent(alpha_):
    a = np.maximum(np.asarray(alpha_, np.float64), DELTA_ALPHA)
    return 2.0 / (a * a) - 2.0


def _lobe_over_4(alpha_, wo, h):
    """(n + 1) (h.z)^n / (8 pi) (N,), and h.wo kept from 1e-6."""
    n = exponent(alpha_)
    cos_h = np.maximum(h[:, 2], 1e-6)
    return (n + 1.0) / (8.0 * np.pi) * np.exp(n * np.log(cos_h)), np.maximum(np.abs(dot(h, wo)), 1e-6)


def eval_reflection(alpha_, wo, wi, F):
    """f (N,3); 0 unless both directions are above the surface."""
    ok = (wo[:, 2] >= 0.0) & (wi[:, 2] >= 0.0)
    h = normalize(wo + wi)
    lobe, cos_oh = _lobe_over_4(alpha_, wo, h)
    pump = 1.0 / np.maximum(1e-6, cos_oh * np.maximum(np.maximum(wo[:, 2], 1e-6), np.maximum(wi[:, 2], 1e-6)))
    return np.asarray(F, np.float64) * np.where(ok, lobe * pump, 0.0)[:, None]


def pdf_reflection(alpha_, wo, wi):
    ok = (wo[:, 2] > 0.0) & (wi[:, 2] > 0.0)
    h = normalize(wo + wi)
    lobe, cos_oh = _lobe_over_4(alpha_, wo, h)
    return np.where(ok & (dot(h, wo) > 0.0), lobe / cos_oh, 0.0)


def sample_reflection(alpha_, wo, u):
    """(wi (N,3), h (N,3), pdf (N,))."""
    n = exponent(np.broadcast_to(alpha_, wo.shape[:1]))
    cos = np.exp(np.log(np.maximum(u[:, 1], 1e-300)) / (n + 1.0))
    sin = np.sqrt(np.maximum(1.0 - cos * cos, 0.0))
    phi = 2.0 * np.pi * u[:, 0]
    h = np.stack([sin * np.cos(phi), sin * np.sin(phi), cos], axis=-1)
    wi = reflect(wo, h)
    ok = (wo[:, 2] > 0.0) & (wi[:, 2] > 0.0) & (dot(h, wo) > 0.0)
    lobe, cos_oh = _lobe_over_4(alpha_, wo, h)
    return wi, h, np.where(ok, lobe / cos_oh, 0.0)
