"""Thin-film iridescence: the Fresnel reflectance of a dielectric film of thickness d (nm) and
index n_f over a dielectric or conducting substrate, in RGB, as Cycles evaluates it
(bsdf_util.h fresnel_iridescence; Belcour and Barla 2017, "A Practical Extension to Microfacet
Theory for the Modeling of Varying Iridescence").

Per polarisation, the Airy sum of the film's multiple reflections is
    R(lambda) = C0 + 2 sum_m Cm cos(m (2 pi OPD / lambda + phi)),
    C0 = R12 + Rs, Rs = T121^2 R23 / (1 - R12 R23), Cm = (Rs - T121) (R12 R23)^(m/2),
with OPD = 2 n_f d cos_2 the optical path difference, phi the phase shifts of the two
reflections (phi23 + phi21, phi21 = phi12 + pi), T121 = 1 - R12. An RGB channel's value is the
integral of R against the channel's colour matching function (CIE 1931 XYZ to Rec.709,
normalised to area 1), which turns each term into S(m OPD) = int cmf(lambda) exp(-2 pi i m OPD
/ lambda) dlambda: the `sensitivity`, tabulated on Cycles' axis (512 nodes of x = 2 pi OPD /
60000 nm in [0, 1], read linearly, clamped). Cycles truncates the sum after m = 3 and averages
the polarisations; below 1 nm the film's index blends toward the ambient one (the wave optics
no longer hold), and a film thinner than CUTOFF is no film at all.

Indices are relative to the ambient medium (1: outside; glass seen from inside passes its
own indices divided by the glass IOR).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from . import fresnel
from ..nodes.color import XYZ_TO_REC709, wavelength_xyz

CUTOFF = 0.1  # nm: THINFILM_THICKNESS_CUTOFF
TABLE_SIZE = 512  # THIN_FILM_TABLE_SIZE
_X_PER_OPD = 2.0 * np.pi / 60000.0  # the table's axis per nm of OPD
_ORDERS = 3


@lru_cache(maxsize=1)
def sensitivity_table() -> np.ndarray:
    """(TABLE_SIZE, 3) complex S at the table's nodes: the trapezoidal integral over 380-780
    nm in 0.25 nm steps of Rec.709 colour matching functions (engine/nodes/color.py's CIE
    table through its XYZ to Rec.709 matrix)."""
    lam = np.arange(380.0, 780.0 + 1e-9, 0.25)
    cmf = wavelength_xyz(lam) @ XYZ_TO_REC709.T  # (L,3)
    w = np.full(len(lam), 0.25)
    w[[0, -1]] = 0.125
    opd = np.arange(TABLE_SIZE) / (TABLE_SIZE - 1) / _X_PER_OPD
    phase = np.exp(-2j * np.pi * opd[:, None] / lam[None, :])  # (T, L)
    return (phase * w) @ cmf / (w @ cmf)


def sensitivity(opd: np.ndarray) -> np.ndarray:
    """(K,3) complex S at optical path differences opd (K,) nm (Cycles' linear table read)."""
    table = sensitivity_table()
    x = np.clip(opd * _X_PER_OPD, 0.0, 1.0) * (TABLE_SIZE - 1)
    i = np.minimum(x.astype(np.int64), TABLE_SIZE - 1)
    i1 = np.minimum(i + 1, TABLE_SIZE - 1)
    t = (x - i)[:, None]
    return (1.0 - t) * table[i] + t * table[i1]


def _dielectric_polarized(cos_i, eta):
    """(R_s, R_p, cos_t, sign_s, sign_p) (K,) at a dielectric interface of relative index eta
    (K,): reflectances, the refracted cosine (negative: across the interface), the signs of the
    amplitude ratios (the phase shift 0 or pi); R = 1 and signs 1 under total internal
    reflection (bsdf_util.h fresnel_dielectric_polarized)."""
    e2 = eta * eta - (1.0 - cos_i * cos_i)
    tir = e2 <= 0.0
    c = np.abs(cos_i)
    cos_t = -np.sqrt(np.maximum(e2, 0.0)) / eta
    den_s, den_p = c - eta * cos_t, eta * c - cos_t
    r_s = np.divide(c + eta * cos_t, den_s, out=np.ones_like(c), where=den_s > 0.0)
    r_p = np.divide(cos_t + eta * c, den_p, out=np.ones_like(c), where=den_p > 0.0)
    sign = lambda r: np.where(tir | (r >= 0.0), 1.0, -1.0)
    one = lambda r: np.where(tir, 1.0, r * r)
    return one(r_s), one(r_p), cos_t, sign(r_s), sign(r_p)


def _airy(R12, R23, opd, phasor):
    """The Airy sum (K,3) of one polarisation: R12 (K,), R23 (K,) or (K,3), phasor exp(i phi)
    (K,) or (K,3) complex."""
    R12 = R12[:, None]
    T121 = 1.0 - R12
    if np.ndim(R23) == 1:
        R23, phasor = R23[:, None], phasor[:, None]
    R123 = R12 * R23
    Rs = np.divide(T121 * T121 * R23, 1.0 - R123, out=np.zeros_like(R123), where=R123 < 1.0)
    R = np.broadcast_to(Rs + R12, (len(opd), 3)).copy()
    Cm = Rs - T121
    r123 = np.sqrt(R123)
    acc = phasor
    for m in range(1, _ORDERS + 1):
        Cm = Cm * r123
        S = sensitivity(m * opd)
        R += 2.0 * Cm * (acc.real * S.real + acc.imag * S.imag)
        acc = acc * phasor
    return R


def _film(cos_1, thickness, film_ior):
    """(index of the film (K,), R12 s and p, cos_2, phase signs of 1->2 s and p, TIR at the top)."""
    n_f = np.where(thickness < 1.0, 1.0 + (film_ior - 1.0) * _smoothstep(thickness), film_ior)
    R12_s, R12_p, cos_2, s12, p12 = _dielectric_polarized(cos_1, n_f)
    return n_f, R12_s, R12_p, cos_2, s12, p12, (R12_s == 1.0) & (R12_p == 1.0)


def _smoothstep(x):
    t = np.clip(x, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def over_dielectric(cos_1, thickness, film_ior, eta):
    """Reflectance (K,3) at cosine cos_1 (K,) of a film (thickness (K,) nm, index film_ior (K,))
    over a dielectric of index eta (K,); 1 under total internal reflection at either interface."""
    n_f, R12_s, R12_p, cos_2, s12, p12, tir = _film(cos_1, thickness, film_ior)
    R23_s, R23_p, _, s23, p23 = _dielectric_polarized(-cos_2, eta / n_f)
    tir |= (R23_s == 1.0) & (R23_p == 1.0)
    opd = -2.0 * n_f * thickness * cos_2
    R = 0.5 * (_airy(R12_s, R23_s, opd, (-s12 * s23).astype(complex))
               + _airy(R12_p, R23_p, opd, (-p12 * p23).astype(complex)))
    return np.where(tir[:, None], 1.0, np.clip(R, 0.0, 1.0))


def over_conductor(cos_1, thickness, film_ior, n, k, F82=None):
    """Reflectance (K,3) of a film over a conductor n + ik (K,3); with F82 (K,3) the conductor's
    reflectance is the F82 model of n, k and F82 (the Principled metal and F82 Metallic BSDF)."""
    n_f, R12_s, R12_p, cos_2, s12, p12, tir = _film(cos_1, thickness, film_ior)
    c = -cos_2
    R23_s, R23_p, (u2, v2, u, v) = fresnel.conductor_polarized(c, n_f, n, k)
    if F82 is not None:  # F0 of n, k relative to the film
        F0 = ((n / n_f[:, None] - 1.0) ** 2 + (k / n_f[:, None]) ** 2) / ((n / n_f[:, None] + 1.0) ** 2
                                                                       + (k / n_f[:, None]) ** 2)
        R23_s = R23_p = fresnel.f82(F0, fresnel.f82_b_of_value(F0, F82), c)
    e1c = (n_f * c)[:, None]
    n2_k2, nk2 = n * n - k * k, 2.0 * n * k
    phasor_s = _unit(-u2 - v2 + e1c * e1c, -2.0 * e1c * v)
    phasor_p = _unit((n * n + k * k) ** 2 * c[:, None] ** 2 - (n_f ** 2)[:, None] * (u2 + v2),
                     2.0 * e1c * (nk2 * u - n2_k2 * v))
    opd = -2.0 * n_f * thickness * cos_2
    R = 0.5 * (_airy(R12_s, R23_s, opd, phasor_s * -s12[:, None]) + _airy(R12_p, R23_p, opd, phasor_p * -p12[:, None]))
    return np.where(tir[:, None], 1.0, np.clip(R, 0.0, 1.0))


def _unit(re, im):
    """re + i im normalised to modulus 1 (1 where it is 0)."""
    mag = np.hypot(re, im)
    ok = mag > 0.0
    return np.where(ok, np.divide(re, mag, out=np.ones_like(re), where=ok), 1.0) + 1j * np.divide(
        im, mag, out=np.zeros_like(im), where=ok)


def nk_from_f82(f0, F82):
    """(n, k) (K,3) a conductor whose F0 and value at ~82 degrees are f0 and F82 (Gulbrandsen
    2014, "Artist Friendly Metallic Fresnel", r = f0 and g = F82, as Cycles' F82 thin film)."""
    r = np.minimum(f0, 0.999)
    sr = np.sqrt(r)
    n = (1.0 - F82) * (1.0 + sr) / (1.0 - sr) + F82 * (1.0 - r) / (1.0 + r)
    k = np.sqrt(np.maximum((r * (n + 1.0) ** 2 - (n - 1.0) ** 2) / (1.0 - r), 0.0))
    return n, k


def scale_to_f0(F, f0, eta):
    """Cycles' Principled F0 scaling of an iridescent dielectric F (K,3): per channel F times
    mix(1, f0 / F0(eta), s), s = clamp((F - 1) / (F0(eta) - 1), 0, 1); f0 (K,3) the specular's
    F0 with its tint and IOR level (bsdf_microfacet.h microfacet_fresnel)."""
    F0 = fresnel.f0_from_ior(eta)[:, None]
    use = (F0 > 1e-5) & ~np.all(F == 1.0, axis=1, keepdims=True)
    s = np.clip(np.divide(F - 1.0, F0 - 1.0, out=np.zeros_like(F), where=F0 != 1.0), 0.0, 1.0)
    factor = np.divide(f0, F0, out=np.ones_like(F), where=F0 > 1e-5)
    return np.where(use, F * (1.0 + (factor - 1.0) * s), F)
