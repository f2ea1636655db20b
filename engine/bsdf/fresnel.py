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
Thin-film iridescence is not modelled.
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
    f0 = np.asarray(f0, dtype=np.float64)
    b = f82_b(f0, tint)
    cos = np.clip(np.asarray(cos, dtype=np.float64), 0.0, 1.0)
    m5 = _one_minus_cos_pow5(cos)
    F = f0 + (1.0 - f0) * m5 - b * (cos[:, None] * m5 * (1.0 - cos[:, None]))
    return np.clip(F, 0.0, 1.0)


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
