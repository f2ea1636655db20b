"""Cycles' Oren-Nayar diffuse (Diffuse BSDF and Principled base with roughness > 0): Fujii's
improved Oren-Nayar ("qualitative" model, https://mimosa-pudica.net/improved-oren-nayar.html)
plus the energy-preserving multiple-scattering term of OpenPBR's EON model, as
kernel/closure/bsdf_oren_nayar.h computes it.

With sigma = roughness in [0, 1], A = 1 / (pi + sigma (pi / 2 - 2 / 3)), B = sigma A, and
cosines mu_o, mu_i of the view and light directions from the shading normal:

    single = A + B t,    t = wo.wi - mu_o mu_i, divided by max(mu_o, mu_i) where positive
    E(mu) = pi A + B G(mu)                       (its directional albedo; G below)
    E_avg = pi A + (2 pi - 5.6) / 3 B
    Ems = rho^2 E_avg / (1 - E_avg) / (1 - rho (1 - E_avg)) / pi,   rho = clamp(colour, 0, 1)
    f = colour (single + Ems (1 - E(mu_o)) (1 - E(mu_i)))

(Cycles weighs the closure by the colour and its multiple-scattering term by rho^2 again: a
white surface reflects all light.) f is symmetric in wo and wi; sampled cosine-weighted.
"""
import numpy as np

_HALF_PI_MINUS = np.pi / 2.0 - 2.0 / 3.0


def coefficients(sigma: np.ndarray):
    """(A, B) (K,) of roughness sigma (K,)."""
    s = np.clip(np.asarray(sigma, np.float64), 0.0, 1.0)
    A = 1.0 / (np.pi + s * _HALF_PI_MINUS)
    return A, s * A


def G(mu: np.ndarray) -> np.ndarray:
    """Fujii's G(mu) (K,): sin (theta - 2/3 - sin cos) + 2/3 tan (1 - sin^3), its Taylor
    expansion near the horizon (where tan misbehaves), as Cycles' bsdf_oren_nayar_G."""
    mu = np.asarray(mu, np.float64)
    c = np.clip(mu, 1e-6, 1.0)
    s = np.sqrt(np.maximum(1.0 - c * c, 0.0))
    theta = np.arccos(c)
    g = s * (theta - 2.0 / 3.0 - s * c) + 2.0 / 3.0 * (s / c) * (1.0 - s * s * s)
    return np.where(mu < 1e-6, _HALF_PI_MINUS - mu, g)


def albedo_E(A, B, mu):
    """E(mu) (K,) = pi A + B G(mu): the single-scattering term's directional albedo."""
    return np.pi * A + B * G(np.maximum(mu, 0.0))


def multiscatter(color: np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Ems (K,3), 0 where B = 0 (Lambertian: nothing is lost)."""
    rho = np.clip(color, 0.0, 1.0)
    E_avg = (np.pi * A + (2.0 * np.pi - 5.6) / 3.0 * B)[:, None]
    lost = 1.0 - E_avg
    ok = lost > 0.0
    den = np.where(ok, lost, 1.0) * (1.0 - rho * lost) * np.pi
    return np.where(ok, rho * rho * E_avg / np.where(den > 0.0, den, 1.0), 0.0)


def eval(color, sigma, wo, wi) -> np.ndarray:
    """f (K,3) per unit solid angle (no cosine): 0 for wi under the surface."""
    A, B = coefficients(sigma)
    mu_o, mu_i = np.maximum(wo[:, 2], 0.0), np.maximum(wi[:, 2], 0.0)
    t = np.einsum("ij,ij->i", wo, wi) - mu_o * mu_i
    t = np.where(t > 0.0, t / (np.maximum(mu_o, mu_i) + 1e-38), t)
    single = A + B * t
    multi = multiscatter(color, A, B) * ((1.0 - albedo_E(A, B, mu_o)) * (1.0 - albedo_E(A, B, mu_i)))[:, None]
    f = color * (single[:, None] + multi)
    return np.where((wi[:, 2] > 0.0)[:, None], f, 0.0)
