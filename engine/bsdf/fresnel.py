"""Fresnel reflectance: exact dielectric, Schlick, and the forms Cycles' Principled BSDF uses.

Cosines are measured from the (micro)surface normal; arrays are float64, one row per shading
point. `eta` is always n_inside / n_outside of the interface (the object's relative IOR); a
negative cosine means the wave arrives from the inside, where the relative index is 1 / eta
(pbrt-v4's FrDielectric convention).

Which model Cycles uses where (blender/blender intern/cycles/kernel/svm/closure.h, Principled
BSDF, and kernel/closure/bsdf_util.h):
  Glass and Refraction BSDF: exact dielectric Fresnel                      -> dielectric()
  Principled metallic lobe: F82-tint Schlick, f0 = base colour,
      tint = min(specular tint, 1) (Kutz et al. 2021, Adobe Standard Material) -> f82_tint()
  Principled dielectric specular and transmission: the exact dielectric Fresnel
      remapped from [F0(ior), 1] onto [f0, f90] (Cycles' GENERALIZED_SCHLICK
      with a negative exponent)                                             -> dielectric_remapped()
  Metallic BSDF, Physical Conductor: the exact conductor Fresnel of n + ik  -> conductor()
Thin-film iridescence on any of them: engine/bsdf/thin_film.py.
"""
import numpy as np

# F82-tint: cos = 1/7 (about 82 degrees) is where Kutz et al. pin the edge tint.
_COS_82 = 1.0 / 7.0


def dielectric_with_cos_t(cos_i, eta):
    """Exact unpolarised Fresnel reflectance F (N,) and the refracted cosine cos_t (N,).

    cos_i (N,): cosine between the incident direction and the normal; < 0 means arriving from
    the inside. eta (N,) or scalar: n_inside / n_outside. cos_t has the sign opposite to cos_i
    (the refracted direction lies on the other side); under total internal reflection F = 1 and
    cos_t = 0. Never NaN: grazing incidence (cos_i = 0) gives F = 1.
    """
    cos_i = np.asarray(cos_i, dtype=np.float64)
    eta = np.broadcast_to(np.asarray(eta, dtype=np.float64), cos_i.shape)
    inside = cos_i < 0.0
    eta_rel = np.where(inside, 1.0 / eta, eta)  # n_transmitted / n_incident
    c_i = np.abs(cos_i)
    sin2_t = (1.0 - c_i * c_i) / (eta_rel * eta_rel)
    tir = sin2_t >= 1.0
    c_t = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    # Amplitude ratios for the two polarisations; both denominators are > 0 unless c_i = c_t = 0.
    den_par = eta_rel * c_i + c_t
    den_perp = c_i + eta_rel * c_t
    r_par = np.divide(eta_rel * c_i - c_t, den_par, out=np.ones_like(c_i), where=den_par > 0.0)
    r_perp = np.divide(c_i - eta_rel * c_t, den_perp, out=np.ones_like(c_i), where=den_perp > 0.0)
    F = np.where(tir, 1.0, 0.5 * (r_par * r_par + r_perp * r_perp))
    cos_t = np.where(tir, 0.0, np.where(inside, c_t, -c_t))
    return F, cos_t


def dielectric(cos_i, eta):
    """Exact unpolarised Fresnel reflectance F (N,) of a dielectric interface (see above)."""
    return dielectric_with_cos_t(cos_i, eta)[0]


def f0_from_ior(eta):
    """Normal-incidence reflectance ((eta - 1) / (eta + 1))^2 of a dielectric."""
    eta = np.asarray(eta, dtype=np.float64)
    return ((eta - 1.0) / (eta + 1.0)) ** 2


def _one_minus_cos_pow5(cos):
    """(1 - cos)^5 for cos clipped to [0, 1], shape (N, 1) for broadcasting against colours."""
    m = np.clip(1.0 - np.asarray(cos, dtype=np.float64), 0.0, 1.0)[:, None]
    m2 = m * m
    return m2 * m2 * m


def schlick(f0, cos):
    """Schlick's approximation f0 + (1 - f0)(1 - cos)^5: f0 (N,3), cos (N,) -> (N,3)."""
    f0 = np.asarray(f0, dtype=np.float64)
    return f0 + (1.0 - f0) * _one_minus_cos_pow5(cos)


def f82_tint(f0, tint, cos):
    """Cycles' Principled metallic Fresnel (F82-tint): f0, tint (N,3), cos (N,) -> (N,3).

    F = Schlick(f0, cos) - b cos (1 - cos)^6, with b chosen so that at cos = 1/7 the value is
    Schlick(f0, 1/7) * tint; clamped to [0, 1] as Cycles does (bsdf_util.h fresnel_f82tint_B,
    fresnel_f82). Cycles takes tint = min(Specular Tint, 1) and f0 = clamped Base Color.
    """
    return f82(np.asarray(f0, dtype=np.float64), f82_b(f0, tint), cos)


def f82(f0, b, cos):
    """The F82 model Schlick(f0, cos) - b cos (1 - cos)^6 clamped to [0, 1] (bsdf_util.h
    fresnel_f82): f0, b (N,3), cos (N,) -> (N,3)."""
    cos = np.clip(np.asarray(cos, dtype=np.float64), 0.0, 1.0)
    m5 = _one_minus_cos_pow5(cos)
    F = f0 + (1.0 - f0) * m5 - b * (cos[:, None] * m5 * (1.0 - cos[:, None]))
    return np.clip(F, 0.0, 1.0)


def f82_b_of_value(f0, F82):
    """The F82 model's b (N,3) for its value F82 (N,3) at cos = 1/7 (bsdf_util.h fresnel_f82_B)."""
    s = 1.0 - _COS_82
    s5 = s ** 5
    f0 = np.asarray(f0, dtype=np.float64)
    return (f0 + (1.0 - f0) * s5 - F82) / (_COS_82 * s5 * s)


def conductor_polarized(cos, eta1, n, k):
    """Reflectances (R_s, R_p) (N,3) of a conductor n + ik (N,3) under a dielectric of index eta1
    (N,) at cosine cos (N,) (Born and Wolf 14.4.1, as bsdf_util.h fresnel_conductor_polarized),
    and the terms (u^2, v^2, u, v) the phase shifts need."""
    c = np.asarray(cos, np.float64)[:, None]
    e1 = np.asarray(eta1, np.float64)[:, None]
    n2_k2 = n * n - k * k
    t1 = n2_k2 - e1 * e1 * (1.0 - c * c)
    t2 = np.sqrt(t1 * t1 + (2.0 * n * k) ** 2)
    u2, v2 = np.maximum(0.5 * (t2 + t1), 0.0), np.maximum(0.5 * (t2 - t1), 0.0)
    u, v = np.sqrt(u2), np.sqrt(v2)
    num_s, den_s = (e1 * c - u) ** 2 + v2, (e1 * c + u) ** 2 + v2
    t3, t4 = n2_k2 * c, 2.0 * n * k * c
    num_p, den_p = (t3 - e1 * u) ** 2 + (t4 - e1 * v) ** 2, (t3 + e1 * u) ** 2 + (t4 + e1 * v) ** 2
    R_s = np.divide(num_s, den_s, out=np.zeros_like(num_s), where=den_s > 0.0)
    R_p = np.divide(num_p, den_p, out=np.zeros_like(num_p), where=den_p > 0.0)
    return R_s, R_p, (u2, v2, u, v)


def conductor(cos, n, k):
    """Unpolarised reflectance (N,3) of a conductor of complex index n + ik (N,3) in vacuum at
    cosine cos (N,) (bsdf_util.h fresnel_conductor)."""
    R_s, R_p, _ = conductor_polarized(np.clip(cos, 0.0, 1.0), np.ones(len(cos)), n, k)
    return 0.5 * (R_s + R_p)


def conductor_fss(n, k):
    """Mean Fresnel (N,3) Cycles gives a conductor (fresnel_conductor_Fss): the F82 model
    through its values at 0 and ~82 degrees, its closed-form mean, clamped to [0, 1]."""
    F0 = conductor(np.ones(len(n)), n, k)
    b = f82_b_of_value(F0, conductor(np.full(len(n), _COS_82), n, k))
    return np.clip(F0 + (1.0 - F0) / 21.0 - b / 126.0, 0.0, 1.0)


def f82_b(f0, tint):
    """The F82-tint model's b (N,3) for f0, tint (N,3): Schlick(f0, 1/7) (1 - tint) / (cos (1 - cos)^6)
    at cos = 1/7 (bsdf_util.h fresnel_f82tint_B)."""
    s = 1.0 - _COS_82
    s5 = s ** 5
    f0 = np.asarray(f0, dtype=np.float64)
    return (f0 + (1.0 - f0) * s5) * (1.0 - np.asarray(tint, dtype=np.float64)) / (_COS_82 * s5 * s)


def dielectric_remapped(f0, cos_i, eta, f90=1.0):
    """Exact dielectric Fresnel remapped from [F0(eta), 1] onto [f0, f90]: (N,3).

    f0 (N,3), cos_i (N,), eta (N,) as in dielectric(); f90 scalar or (N,3). This is Cycles'
    Principled specular and transmission Fresnel (bsdf_microfacet.h, GENERALIZED_SCHLICK with
    exponent < 0): with f0 = F0(eta) and f90 = 1 it is exactly dielectric(cos_i, eta). Under
    total internal reflection it gives f90.
    """
    F = dielectric(cos_i, eta)
    F0 = f0_from_ior(eta)  # the same from either side: symmetric under eta -> 1 / eta
    span = 1.0 - F0
    s = np.clip(np.divide(F - F0, span, out=np.ones_like(F), where=span > 0.0), 0.0, 1.0)
    f0 = np.asarray(f0, dtype=np.float64)
    return f0 + (np.asarray(f90, dtype=np.float64) - f0) * s[:, None]
