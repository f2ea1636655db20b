"""Physically plausible (energy-normalised) Phong BRDF, as seed 000 appendix A defines it.

    f(wo, wi) = kd / pi + ks (n + 2) / (2 pi) cos^n(alpha),   cos(alpha) = wi . R(wo) > 0,

R(wo) the mirror direction of wo; kd + ks <= 1 per channel keeps it energy conserving (the
caller's materials guarantee it). Sampling (seed 000; Mitsuba 0.6 phong.cpp, SmallVCM bsdf.hxx):
choose the lobe with P_d = max(kd) / (max(kd) + max(ks)), else the glossy lobe; diffuse is
cosine-weighted, glossy has density (n + 1) / (2 pi) cos^n(alpha) around R. A direction under
the surface gets weight 0 and pdf 0, without a redraw. The pdf returned for MIS and used in the
throughput is the mixture P_d cos_i / pi + P_s (n + 1) / (2 pi) cos^n(alpha), so the estimator
is unbiased whichever lobe produced the direction.

Everything is in the local shading frame (z = shading normal), float64, one row per shading
point: kd, ks (N,3); n (N,) exponents; wo, wi (N,3) unit vectors with wo toward the viewer.
f is zero unless wo.z > 0 and wi.z > 0 (the same rule both ways, so f is reciprocal).

Stable up to n = 1e6 (algorithms.md, hard case 4): R is built once per call in float64; the
sampled cos(alpha) = exp(ln u / (n + 1)) and sin^2(alpha) = -expm1(2 ln u / (n + 1)); at
evaluation 1 - cos(alpha) = |wi - R|^2 / 2 (chord form, no cancellation) and
cos^n = exp(n log1p(-(1 - cos))). The lobe is about sqrt(2 / n) rad wide (1.4e-3 at 1e6).
"""
import numpy as np

from .. import sampling
from ..vec import max3


def _lobe_probabilities(kd, ks):
    """(P_d, P_s) (N,): max reflectance of each lobe over their sum; both 0 for a black BRDF."""
    p_d, p_s = max3(kd), max3(ks)
    total = p_d + p_s
    P_d = np.divide(p_d, total, out=np.zeros(len(kd)), where=total > 0.0)
    P_s = np.divide(p_s, total, out=np.zeros(len(kd)), where=total > 0.0)
    return P_d, P_s


def _mirror(wo):
    """Mirror direction R (N,3) of wo about the local normal +z (exact in the local frame)."""
    return wo * np.array([-1.0, -1.0, 1.0])


def _cos_pow_n(n, wi, R):
    """cos^n(alpha) (N,) for cos(alpha) = wi . R, 0 where cos(alpha) <= 0; via the chord."""
    d = wi - R
    one_minus_cos = 0.5 * (d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])
    lobe = one_minus_cos < 1.0
    x = np.where(lobe, one_minus_cos, 0.0)
    return np.where(lobe, np.exp(np.asarray(n, dtype=np.float64) * np.log1p(-x)), 0.0)


def _both_above(wo, wi):
    return (wo[:, 2] > 0.0) & (wi[:, 2] > 0.0)


def eval(kd, ks, n, wo, wi):
    """f (N,3) per steradian; 0 unless wo and wi are above the surface."""
    n = np.asarray(n, dtype=np.float64)
    glossy = (n + 2.0) / (2.0 * np.pi) * _cos_pow_n(n, wi, _mirror(wo))
    f = kd / np.pi + ks * glossy[:, None]
    return np.where(_both_above(wo, wi)[:, None], f, 0.0)


def pdf(kd, ks, n, wo, wi):
    """Solid-angle pdf (N,) of sample(): the lobe mixture; 0 under the surface or for black."""
    n = np.asarray(n, dtype=np.float64)
    P_d, P_s = _lobe_probabilities(kd, ks)
    glossy = (n + 1.0) / (2.0 * np.pi) * _cos_pow_n(n, wi, _mirror(wo))
    p = P_d * wi[:, 2] / np.pi + P_s * glossy
    return np.where(_both_above(wo, wi), p, 0.0)


def diffuse_probability(kd, ks):
    """(N,) probability that sample() takes its diffuse lobe (u_lobe below it)."""
    return _lobe_probabilities(kd, ks)[0]


def sample(kd, ks, n, wo, u, u_lobe):
    """Sample wi: returns (wi (N,3), weight (N,3) = f cos_i / pdf, pdf (N,) the mixture).

    u (N,2) for the direction, u_lobe (N,) for the lobe choice. Samples under the surface keep
    their direction but get weight 0 and pdf 0 (no redraw), as do rows with a black BRDF.
    """
    n = np.asarray(n, dtype=np.float64)
    u = np.clip(np.asarray(u, dtype=np.float64), 0.0, sampling.ONE_MINUS_EPSILON)
    P_d, _ = _lobe_probabilities(kd, ks)
    wi_diffuse = sampling.sample_cosine_hemisphere(u)
    # cos^(n+1)(alpha) = 1 - u0 is uniform; log1p keeps ln(1 - u0) accurate and finite.
    ln_u = np.log1p(-u[:, 0]) / (n + 1.0)
    cos_a = np.exp(ln_u)
    sin_a = np.sqrt(-np.expm1(2.0 * ln_u))
    phi = 2.0 * np.pi * u[:, 1]
    R = _mirror(wo)
    t, b = sampling.frame_from_z(R)
    local = np.stack([sin_a * np.cos(phi), sin_a * np.sin(phi), cos_a], axis=-1)
    wi_glossy = sampling.to_world(local, t, b, R)
    wi = np.where((np.asarray(u_lobe) < P_d)[:, None], wi_diffuse, wi_glossy)
    p = pdf(kd, ks, n, wo, wi)
    f_cos = eval(kd, ks, n, wo, wi) * wi[:, 2:3]
    weight = np.divide(f_cos, p[:, None], out=np.zeros_like(f_cos), where=(p > 0.0)[:, None])
    return wi, weight, p


def albedo(kd, ks, n, wo):
    """Directional-albedo estimate (N,3) for Russian roulette: kd + ks, 0 if wo.z <= 0.

    An upper bound: the diffuse part is exactly kd, and the glossy part is ks at normal
    incidence (the normalisation makes it so) and less elsewhere (about ks cos(theta_o) for
    narrow lobes, more for wide ones clipped by the horizon).
    """
    return np.where((wo[:, 2] > 0.0)[:, None], kd + ks, 0.0)
