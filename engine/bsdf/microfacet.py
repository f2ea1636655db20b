"""Isotropic GGX (Trowbridge-Reitz) microfacet distribution and its reflection lobe, as Cycles.

Everything is in the local shading frame (z = shading normal), float64, one row per shading
point: directions (N,3) unit vectors, `alpha` (N,) or scalar. wo points toward the viewer,
wi is the sampled / light direction, h the microfacet normal. Pdfs are per unit solid angle.

Conventions, checked against Blender Cycles (blender/blender intern/cycles):
- alpha = roughness^2 (svm/closure.h: Glossy, Glass, Refraction and Principled set
  alpha_x = alpha_y = sqr(roughness)); `alpha_from_roughness` does the mapping.
- Smith masking-shadowing in the height-correlated form G2 = 1 / (1 + Lambda(wo) + Lambda(wi))
  (kernel/closure/bsdf_microfacet.h bsdf_G, Heitz 2014 eq. 72 for Lambda).
- Visible-normal sampling (Heitz 2018, "Sampling the GGX Distribution of Visible Normals",
  JCGT 7(4)), as microfacet_ggx_sample_vndf; the pdf of a reflected direction is
  G1(wo) D(h) / (4 cos_o).
- A lobe with alpha^2 <= 2e-10 (BSDF_ROUGHNESS_SQ_THRESH; roughness <= 0.00376) is a perfect
  mirror in Cycles: it has no eval and is sampled as a delta. `is_delta` marks those rows; the
  functions here must not be used for them (D would overflow toward a Dirac).
- Cycles' "Multiscatter GGX" (the default distribution of Glossy, Glass, Metallic and
  Principled in Blender 5.0) is this lobe times an energy compensation of wo
  (engine/bsdf/multiscatter.py), applied by the lobes (engine/bsdf/lobes/).
"""
import numpy as np

from .. import sampling
from ..vec import dot, normalize

DELTA_ALPHA2 = 2e-10


def alpha_from_roughness(roughness):
    """GGX alpha (N,) from Blender's roughness (N,) in [0, 1]: alpha = roughness^2."""
    return np.clip(np.asarray(roughness, dtype=np.float64), 0.0, 1.0) ** 2


def is_delta(alpha):
    """(N,) bool: rows whose lobe callers must treat as a perfect mirror / sharp refraction."""
    alpha = np.asarray(alpha, dtype=np.float64)
    return alpha * alpha <= DELTA_ALPHA2


def D(alpha, h):
    """GGX normal distribution D(h) (N,), per unit solid angle of h; 0 for h.z <= 0.

    alpha^2 / (pi (sin^2 + alpha^2 cos^2)^2) with sin^2 = h.x^2 + h.y^2 taken directly, so a
    half vector 1e-6 rad from the normal keeps its precision (no 1 - cos^2 cancellation).
    """
    a2 = np.asarray(alpha, dtype=np.float64) ** 2
    sin2 = h[:, 0] * h[:, 0] + h[:, 1] * h[:, 1]
    den = np.pi * (sin2 + a2 * h[:, 2] * h[:, 2]) ** 2
    return np.divide(a2, den, out=np.zeros(len(h)), where=(h[:, 2] > 0.0) & (den > 0.0))


def _sqrt_1_plus_a2_tan2(alpha, w):
    """sqrt(1 + alpha^2 tan^2 theta) (N,) of directions w (N,3); Inf on the horizon."""
    a2 = np.asarray(alpha, dtype=np.float64) ** 2
    z2 = w[:, 2] * w[:, 2]
    a2_tan2 = np.divide(a2 * (w[:, 0] * w[:, 0] + w[:, 1] * w[:, 1]), z2,
                        out=np.full(len(w), np.inf), where=z2 > 0.0)
    return np.sqrt(1.0 + a2_tan2)


def G1(alpha, w):
    """Smith masking G1(w) = 1 / (1 + Lambda(w)) (N,), Lambda = (sqrt(1 + a^2 tan^2) - 1) / 2.

    Written as 2 / (1 + sqrt(1 + a^2 tan^2)): no cancellation for tiny alpha, 0 on the horizon.
    Depends on |w.z| only (the same for directions below the surface, as in Cycles).
    """
    return 2.0 / (1.0 + _sqrt_1_plus_a2_tan2(alpha, w))


def G2(alpha, wo, wi):
    """Height-correlated masking-shadowing G2 (N,) = 1 / (1 + Lambda(wo) + Lambda(wi)), as
    Cycles' bsdf_G."""
    return 2.0 / (_sqrt_1_plus_a2_tan2(alpha, wo) + _sqrt_1_plus_a2_tan2(alpha, wi))


def sample_vndf(alpha, wo, u, alpha_y=None):
    """Microfacet normals h (N,3) distributed as the visible normals D_wo(h) = G1 (wo.h)+ D / wo.z.

    wo (N,3) with wo.z > 0; u (N,2); alpha_y (N,) the roughness along y where it differs from
    alpha's along x (anisotropic GGX). Heitz 2018: stretch wo to the hemisphere configuration,
    sample the projected half disk (here through the concentric map, as Cycles), reproject,
    unstretch.
    """
    alpha = np.broadcast_to(np.asarray(alpha, dtype=np.float64), wo.shape[:1])
    alpha_y = alpha if alpha_y is None else alpha_y
    v = normalize(np.stack([alpha * wo[:, 0], alpha_y * wo[:, 1], wo[:, 2]], axis=-1))
    len2 = v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1]
    inv_len = np.divide(1.0, np.sqrt(len2), out=np.zeros(len(v)), where=len2 > 0.0)
    # Basis (t1, t2, v); at normal incidence any tangent will do.
    t1 = np.where((len2 > 0.0)[:, None],
                  np.stack([-v[:, 1] * inv_len, v[:, 0] * inv_len, np.zeros(len(v))], axis=-1),
                  np.array([1.0, 0.0, 0.0]))
    t2 = np.cross(v, t1)
    disk = sampling.sample_concentric_disk(u)
    p1 = disk[:, 0]
    s = 0.5 * (1.0 + v[:, 2])
    # Warp the disk to the part of the projected hemisphere that wo sees.
    p2 = (1.0 - s) * np.sqrt(np.maximum(0.0, 1.0 - p1 * p1)) + s * disk[:, 1]
    pz = np.sqrt(np.maximum(0.0, 1.0 - p1 * p1 - p2 * p2))
    nh = p1[:, None] * t1 + p2[:, None] * t2 + pz[:, None] * v
    return normalize(np.stack([alpha * nh[:, 0], alpha_y * nh[:, 1], np.maximum(0.0, nh[:, 2])],
                              axis=-1))


def reflect(wo, h):
    """Mirror wo (N,3) about h (N,3): 2 (wo.h) h - wo."""
    return 2.0 * dot(wo, h)[:, None] * h - wo


def pdf_reflection(alpha, wo, wi):
    """Solid-angle pdf (N,) of sample_reflection at wi: G1(wo) D(h) / (4 wo.z), h = |wo + wi|.

    0 unless wo and wi are both above the surface (samples below it are discarded).
    """
    ok = (wo[:, 2] > 0.0) & (wi[:, 2] > 0.0)
    h = normalize(wo + wi)
    num = G1(alpha, wo) * D(alpha, h)
    return np.divide(num, 4.0 * wo[:, 2], out=np.zeros(len(wo)), where=ok)


def eval_reflection(alpha, wo, wi, F):
    """f (N,3) = F D(h) G2 / (4 cos_o cos_i); F (N,3) is the Fresnel term at h = |wo + wi|.

    0 unless both directions are above the surface. Cosines so small that their product
    underflows (1e-300) give 0, not 0 / 0 = NaN (G2 is 0 there).
    """
    den = 4.0 * wo[:, 2] * wi[:, 2]
    ok = (wo[:, 2] > 0.0) & (wi[:, 2] > 0.0) & (den > 0.0)
    h = normalize(wo + wi)
    s = np.divide(D(alpha, h) * G2(alpha, wo, wi), den, out=np.zeros(len(wo)), where=ok)
    return np.asarray(F, dtype=np.float64) * s[:, None]


def sample_reflection(alpha, wo, u):
    """Sample a reflected direction: (wi (N,3), h (N,3), pdf (N,)).

    h from the visible normals, wi = wo mirrored about h. A wi below the surface is returned
    with pdf 0 (the caller gives it weight 0; no redraw). For F = 1 the throughput weight
    f cos_i / pdf is G2 / G1(wo); callers multiply by their Fresnel term at h.
    """
    h = sample_vndf(alpha, wo, u)
    wi = reflect(wo, h)
    ok = (wo[:, 2] > 0.0) & (wi[:, 2] > 0.0)
    num = G1(alpha, wo) * D(alpha, h)
    pdf = np.divide(num, 4.0 * wo[:, 2], out=np.zeros(len(wo)), where=ok)
    return wi, h, pdf
